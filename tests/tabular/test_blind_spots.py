"""Properties of the tabular update rules that the hand-worked examples do not reach.

Each test states what the equation says (Sutton & Barto, 2nd ed.) on a case chosen so
that a wrong rule gives different numbers: tied action values, truncated episodes,
states visited twice in an episode, one action per state, importance sampling for V.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import td_kernels as tdk
from policylab.tabular.kernels import (
    epsilon_greedy_action,
    epsilon_greedy_prob,
    greedy_action,
    rng_states,
)


# ----------------------------------------------------------------------------- epsilon-greedy
def eps_greedy_by_definition(q: np.ndarray, mask: np.ndarray, eps: float) -> np.ndarray:
    """pi(a | s) = eps / |A(s)| + (1 - eps) / |argmax| on each maximiser (S&B section 5.4)."""
    qa = np.where(mask, q, -np.inf)
    best = mask & (qa == qa.max())
    return mask * eps / mask.sum() + best * (1.0 - eps) / best.sum()


ROWS = [
    ([1.0, 1.0, 0.0], [True, True, True]),
    ([2.0, 2.0, 2.0], [True, True, True]),
    ([0.0, 3.0, 3.0, -1.0], [True, False, True, True]),  # a masked action holds no mass
    ([5.0, 1.0, 1.0, 1.0], [False, True, True, True]),  # the masked best is not best
    ([0.5, -2.0], [True, True]),
]


@pytest.mark.parametrize("eps", [0.0, 0.1, 0.5, 1.0])
@pytest.mark.parametrize(("q", "mask"), ROWS)
def test_epsilon_greedy_prob_is_a_distribution_over_available_actions_with_ties(q, mask, eps):
    q, mask = np.array(q), np.array(mask)
    probs = np.array([epsilon_greedy_prob(q, mask, eps, a) for a in range(q.size)])
    want = eps_greedy_by_definition(q, mask, eps)
    np.testing.assert_allclose(probs[mask], want[mask], rtol=0, atol=1e-15)
    assert probs[mask].sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(("q", "mask"), ROWS[:3])
def test_epsilon_greedy_prob_is_the_frequency_of_epsilon_greedy_action(q, mask):
    """The probability the learners use for b(A | S) is the one the action choice draws with."""
    q, mask = np.array(q), np.array(mask)
    eps, n = 0.3, 40_000
    state = rng_states(5)[0]
    counts = np.bincount(
        [epsilon_greedy_action(q, mask, eps, state) for _ in range(n)], minlength=q.size
    )
    probs = np.array([epsilon_greedy_prob(q, mask, eps, a) for a in range(q.size)])
    assert np.all(counts[~mask] == 0)
    # 5 standard errors of a binomial frequency; the seed is fixed, so this is not flaky.
    np.testing.assert_allclose(counts[mask] / n, probs[mask], atol=5 * np.sqrt(0.25 / n))


@pytest.mark.parametrize("eps", [0.0, 0.1, 1.0])
@pytest.mark.parametrize(("q", "mask"), ROWS)
def test_expected_sarsa_target_is_the_expectation_under_epsilon_greedy(q, mask, eps):
    """R + gamma sum_a pi(a | S') Q(S', a) (S&B eq. 6.9), ties sharing the greedy mass."""
    q, mask = np.array(q), np.array(mask)
    r, gamma = 0.5, 0.9
    pi = eps_greedy_by_definition(q, mask, eps)
    want = r + gamma * float(np.sum(pi[mask] * q[mask]))
    got = tdk.expected_sarsa_target(r, gamma, q, mask, eps, False)
    assert got == pytest.approx(want, abs=1e-12)
    assert tdk.expected_sarsa_target(r, gamma, q, mask, eps, True) == r


def test_expected_sarsa_target_with_a_tie_by_hand():
    # q = [1, 1, 0], eps = 0.1: pi = [0.1/3 + 0.45, 0.1/3 + 0.45, 0.1/3], E[Q] = 0.9 + 0.2/3.
    q, mask = np.array([1.0, 1.0, 0.0]), np.ones(3, dtype=bool)
    assert tdk.expected_sarsa_target(0.0, 1.0, q, mask, 0.1, False) == pytest.approx(0.9 + 0.2 / 3)


# ----------------------------------------------------------------------------- truncation
TRUNC = dict(episodes=40, alpha=0.2, init=0.5, seed=3, checkpoints=3, max_steps=3)


def same(a, b):
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.episode_returns, b.episode_returns)
    assert a.steps == b.steps


def test_n_step_td_with_n_1_is_td0_when_episodes_are_truncated():
    """A time limit bootstraps: G = R + gamma V(S_T) for the last step of a cut episode,
    in n-step TD as in TD(0). The random walk from its centre needs at least 3 steps."""
    mdp = pl.problems.random_walk()
    td0 = tab.td0(mdp, **TRUNC)
    assert td0.truncated > 0
    same(tab.n_step_td(mdp, n=1, **TRUNC), td0)
    for trace in ("accumulating", "replacing"):
        same(tab.td_lambda(mdp, lam=0.0, trace=trace, **TRUNC), td0)


def test_n_step_sarsa_with_n_1_is_sarsa_when_episodes_are_truncated():
    mdp = pl.problems.cliff_walking()
    kw = dict(episodes=30, alpha=0.5, epsilon=0.1, seed=7, checkpoints=3, max_steps=15)
    sarsa = tab.sarsa(mdp, **kw)
    assert sarsa.truncated > 0
    same(tab.n_step_sarsa(mdp, n=1, **kw), sarsa)


def test_truncated_td0_bootstraps_from_the_last_state():
    """alpha = 1 and one episode cut after one step: V(S_0) <- R_1 + gamma V(S_1), with
    V(S_1) = init since S_1 is not terminal (a terminal S_1 would give R_1 alone)."""
    mdp = pl.problems.random_walk()
    res = tab.td0(mdp, episodes=1, alpha=1.0, init=0.5, seed=0, max_steps=1, checkpoints=1)
    assert res.truncated == 1
    changed = np.flatnonzero(res.v != np.where(mdp.terminal, 0.0, 0.5))
    # From the centre (C) one step reaches B or D, never a terminal state: the target is
    # 0 + 1 * 0.5, so V is unchanged; nothing moves.
    assert changed.size == 0


# ----------------------------------------------------------------------------- traces
def self_loop(p_stay: float = 0.7) -> pl.FiniteMDP:
    """One state with one action: back to itself w.p. p_stay, else the end; reward 1."""
    return pl.FiniteMDP.from_dynamics(
        {"s": {"go": [(p_stay, "s", 1.0), (1 - p_stay, "end", 1.0)]}}, gamma=0.9, terminal=("end",)
    )


def td_lambda_by_hand(lengths, lam, gamma, alpha, replacing):
    """Online tabular TD(lambda) on the self-loop, every step of every episode (S&B 12.2):
    delta = R + gamma V(S') - V(S); z <- z + 1 (accumulating) or z <- 1 (replacing);
    V <- V + alpha delta z; z <- gamma lambda z. All rewards are 1 and S' = s until the
    last step, where S' is terminal."""
    v = 0.0
    for T in lengths:
        z = 0.0
        for t in range(T):
            last = t == T - 1
            delta = 1.0 + (0.0 if last else gamma * v) - v
            z = 1.0 if replacing else z + 1.0
            v += alpha * delta * z
            z *= gamma * lam
    return v


def test_replacing_and_accumulating_traces_on_a_state_visited_many_times():
    mdp = self_loop()
    kw = dict(lam=0.9, episodes=30, alpha=0.05, seed=1, checkpoints=2)
    acc = tab.td_lambda(mdp, trace="accumulating", **kw)
    rep = tab.td_lambda(mdp, trace="replacing", **kw)
    lengths = acc.episode_lengths
    np.testing.assert_array_equal(lengths, rep.episode_lengths)  # same seed, same episodes
    assert lengths.max() > 1  # the state is revisited, so the two traces must part
    want_acc = td_lambda_by_hand(lengths, 0.9, 0.9, 0.05, replacing=False)
    want_rep = td_lambda_by_hand(lengths, 0.9, 0.9, 0.05, replacing=True)
    assert acc.v[0] == pytest.approx(want_acc, rel=1e-12)
    assert rep.v[0] == pytest.approx(want_rep, rel=1e-12)
    assert abs(want_acc - want_rep) > 0.01


# ----------------------------------------------------------------------------- Monte Carlo
def one_action_chain() -> pl.FiniteMDP:
    """Two states, one action each, with revisits: a -> a | b | end, b -> a | end."""
    return pl.FiniteMDP.from_dynamics(
        {
            "a": {"go": [(0.5, "a", 1.0), (0.3, "b", -2.0), (0.2, "end", 3.0)]},
            "b": {"go": [(0.6, "a", 0.5), (0.4, "end", 0.0)]},
        },
        gamma=0.9,
        terminal=("end",),
    )


@pytest.mark.parametrize("first_visit", [True, False])
def test_monte_carlo_v_equals_q_when_each_state_has_one_action(first_visit):
    """With A(s) = {go}, v_pi(s) = q_pi(s, go) and the visits of s are the visits of
    (s, go): first-visit (or every-visit) averages of G must agree to rounding."""
    mdp = one_action_chain()
    res = tab.mc_prediction(mdp, episodes=400, first_visit=first_visit, seed=2, checkpoints=2)
    live = ~mdp.terminal
    np.testing.assert_allclose(res.v[live], res.q[live, 0], rtol=0, atol=1e-12)


def test_first_and_every_visit_differ_on_revisits():
    """The problem above revisits states, so the first-visit flag changes the estimate."""
    mdp = one_action_chain()
    fv = tab.mc_prediction(mdp, episodes=400, first_visit=True, seed=2, checkpoints=2)
    ev = tab.mc_prediction(mdp, episodes=400, first_visit=False, seed=2, checkpoints=2)
    assert np.max(np.abs(fv.v - ev.v)) > 1e-3
    # First-visit counts one update per episode that reaches s, at most one per episode.
    assert np.all(fv.counts[:, 0] <= 400)
    assert np.all(ev.counts[:, 0] >= fv.counts[:, 0])


def one_step_choice() -> pl.FiniteMDP:
    """One decision: "good" pays 1, "bad" pays 0, both end the episode."""
    return pl.FiniteMDP.from_dynamics(
        {"s": {"good": [(1.0, "end", 1.0)], "bad": [(1.0, "end", 0.0)]}},
        gamma=1.0,
        terminal=("end",),
    )


@pytest.mark.parametrize("weighted", [False, True])
def test_off_policy_monte_carlo_v_under_a_uniform_behaviour(weighted):
    """Target pi(s) = good (v_pi(s) = 1), behaviour uniform: rho = pi / b = 2 on "good",
    0 on "bad". Ordinary IS: V(s) = (1/N) sum rho G = 2 N_good / N. Weighted IS:
    V(s) = sum rho G / sum rho = 1 exactly once "good" has been tried."""
    mdp = one_step_choice()
    pi = pl.Policy.deterministic(mdp, {"s": "good"})
    n = 301
    res = tab.mc_off_policy(mdp, pi, weighted=weighted, episodes=n, seed=4, checkpoints=2)
    n_good = res.counts[0, mdp.actions.index("good")]
    assert 0 < n_good < n
    want = 1.0 if weighted else 2.0 * n_good / n
    assert res.v[0] == pytest.approx(want, rel=1e-12)
    assert res.q[0, mdp.actions.index("good")] == pytest.approx(1.0, rel=1e-12)


def deterministic_line() -> pl.FiniteMDP:
    """States 0..3 on a line, 3 terminal; "right" moves right, "left" moves left (0 stays);
    every step costs 1."""
    dyn = {}
    for s in range(3):
        dyn[s] = {
            "left": [(1.0, max(s - 1, 0), -1.0)],
            "right": [(1.0, s + 1, -1.0)],
        }
    return pl.FiniteMDP.from_dynamics(dyn, gamma=0.9, terminal=(3,))


def test_weighted_importance_sampling_v_is_exact_on_a_deterministic_problem():
    """Weighted IS averages G_t over the visits whose later actions all follow pi (the
    others weigh 0). With deterministic dynamics and rewards each such G_t equals
    v_pi(S_t), so V = v_pi on every state visited under a positive weight."""
    mdp = deterministic_line()
    pi = pl.Policy.deterministic(mdp, {s: "right" for s in range(3)})
    v_pi = pl.evaluate_policy(mdp, pi)
    res = tab.mc_off_policy(mdp, pi, weighted=True, episodes=300, seed=6, checkpoints=2)
    np.testing.assert_allclose(res.v, v_pi, rtol=0, atol=1e-12)
    ordinary = tab.mc_off_policy(mdp, pi, weighted=False, episodes=20_000, seed=6, checkpoints=2)
    np.testing.assert_allclose(ordinary.v, v_pi, atol=0.25)


# ----------------------------------------------------------------------------- greedy choices
@pytest.mark.parametrize(("q", "mask"), ROWS)
def test_greedy_action_and_q_learning_max_range_over_available_actions_only(q, mask):
    """argmax_{a in A(s)} Q(s, a) and R + gamma max_{a in A(s')} Q(s', a) (S&B eq. 6.8):
    an unavailable action never wins, even with the largest entry of the row."""
    q, mask = np.array(q), np.array(mask)
    best = int(np.flatnonzero(mask & (q == q[mask].max()))[0])
    assert greedy_action(q, mask) == best
    qt, mt = q[None, :], mask[None, :]
    assert tdk.q_learning_target(1.0, 0.5, qt, mt, 0, False) == 1.0 + 0.5 * q[mask].max()
    assert tdk.q_learning_target(1.0, 0.5, qt, mt, 0, True) == 1.0


def test_double_q_target_values_the_argmax_of_one_table_with_the_other():
    """R + gamma Q2(S', argmax_a Q1(S', a)) (S&B eq. 6.10), argmax over A(S') only."""
    q1 = np.array([0.0, 5.0, 1.0, 9.0])
    q2 = np.array([7.0, -1.0, 3.0, 100.0])
    mask = np.array([True, True, True, False])
    assert tdk.double_q_target(0.5, 0.9, q1, q2, mask, False) == 0.5 + 0.9 * -1.0
    assert tdk.double_q_target(0.5, 0.9, q2, q1, mask, False) == 0.5 + 0.9 * 0.0


# ----------------------------------------------------------------------------- first visits
def revisiting_start() -> pl.FiniteMDP:
    """Two actions per state and revisits of the start state A (B may lead back to A)."""
    return pl.FiniteMDP.from_dynamics(
        {
            "A": {"x": [(1.0, "A", 1.0)], "y": [(1.0, "B", 2.0)]},
            "B": {"x": [(0.5, "A", -1.0), (0.5, "end", 0.0)], "y": [(1.0, "end", 3.0)]},
        },
        gamma=0.9,
        terminal=("end",),
    )


def test_first_visit_v_of_the_start_state_is_the_mean_episode_return():
    """Every episode starts in A, so A's first visit is t = 0 and first-visit MC with
    sample averages gives V(A) = mean of G_0 over the episodes (S&B section 5.1);
    every-visit MC, which also averages the returns of later visits, does not."""
    mdp = revisiting_start()
    kw = dict(episodes=300, seed=8, checkpoints=2, start="A")
    fv = tab.mc_prediction(mdp, first_visit=True, **kw)
    assert fv.truncated == 0
    a = mdp.states.index("A")
    assert fv.v[a] == pytest.approx(np.mean(fv.episode_returns), rel=1e-12)
    ev = tab.mc_prediction(mdp, first_visit=False, **kw)
    assert abs(ev.v[a] - np.mean(ev.episode_returns)) > 1e-3


# ----------------------------------------------------------------------------- importance weights
def two_step_choice() -> pl.FiniteMDP:
    """s0 --go, 0--> s1; in s1 "good" pays 1 and "bad" pays 0, both end the episode."""
    return pl.FiniteMDP.from_dynamics(
        {
            "s0": {"go": [(1.0, "s1", 0.0)]},
            "s1": {"good": [(1.0, "end", 1.0)], "bad": [(1.0, "end", 0.0)]},
        },
        gamma=1.0,
        terminal=("end",),
    )


def test_off_policy_monte_carlo_q_weighs_the_return_by_the_later_ratios():
    """Ordinary IS for Q(s0, go): W = rho_1 = pi(A_1 | s1) / b(A_1 | s1), which is 2 when
    A_1 = good (the target's action under a uniform b) and 0 otherwise, so
    Q(s0, go) = (1/N) sum W G = 2 N_good / N; the same holds for off-policy control,
    whose greedy target picks good (tied first, then strictly better)."""
    mdp = two_step_choice()
    s0, s1, good = mdp.states.index("s0"), mdp.states.index("s1"), mdp.actions.index("good")
    go = mdp.actions.index("go")
    n = 257
    pi = pl.Policy.deterministic(mdp, {"s0": "go", "s1": "good"})
    for target in (pi, None):
        res = tab.mc_off_policy(mdp, target, episodes=n, seed=9, checkpoints=2, start="s0")
        n_good = res.counts[s1, good]
        assert 0 < n_good < n
        assert res.q[s0, go] == pytest.approx(2.0 * n_good / n, rel=1e-12)
        assert res.q[s1, good] == pytest.approx(1.0, rel=1e-12)


# ----------------------------------------------------------------------------- V(terminal) = 0
class OneStep(gym.Env):
    """A Gymnasium env with no model behind it: state 0, one action, then state 1, which
    ends the episode with reward 1. The learner cannot know state 1 is terminal before
    it sees ``terminated``, so its table holds the initial value there."""

    observation_space = gym.spaces.Discrete(2)
    action_space = gym.spaces.Discrete(1)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return 0, {}

    def step(self, action):
        return 1, 1.0, True, False, {}


@pytest.mark.parametrize("learner", ["td0", "n_step_td", "td_lambda"])
def test_a_terminated_step_does_not_bootstrap_from_the_table(learner):
    """V(S) <- V(S) + alpha [R - V(S)] when S' is terminal (v(terminal) = 0, S&B eq. 6.2),
    whatever the table holds for S': with alpha = 1, V(0) = R = 1 after one episode."""
    res = getattr(tab, learner)(OneStep(), episodes=1, alpha=1.0, init=0.5, seed=0, checkpoints=1)
    assert res.v[0] == 1.0


def noisy_one_step_choice() -> pl.FiniteMDP:
    """One decision: "good" pays 1 or 3 (even odds), "bad" pays 0; both end the episode."""
    return pl.FiniteMDP.from_dynamics(
        {
            "s": {
                "good": [(0.5, "end", 1.0), (0.5, "end", 3.0)],
                "bad": [(1.0, "end", 0.0)],
            }
        },
        gamma=1.0,
        terminal=("end",),
    )


@pytest.mark.parametrize("weighted", [False, True])
def test_off_policy_monte_carlo_v_with_random_returns_by_hand(weighted):
    """Target pi(s) = good, uniform behaviour: rho = 2 on "good" episodes (G = 1 or 3) and
    0 on "bad" ones (G = 0). Ordinary IS: V(s) = (1/N) sum rho G = 2 mean(G). Weighted
    IS: V(s) = sum rho G / sum rho, the mean return of the "good" episodes."""
    mdp = noisy_one_step_choice()
    pi = pl.Policy.deterministic(mdp, {"s": "good"})
    res = tab.mc_off_policy(mdp, pi, weighted=weighted, episodes=400, seed=12, checkpoints=2)
    g = res.episode_returns
    assert np.any(g == 1.0) and np.any(g == 3.0) and np.any(g == 0.0)
    want = np.mean(g[g > 0]) if weighted else 2.0 * np.mean(g)
    assert res.v[0] == pytest.approx(want, rel=1e-12)
    assert res.q[0, mdp.actions.index("good")] == pytest.approx(np.mean(g[g > 0]), rel=1e-12)
