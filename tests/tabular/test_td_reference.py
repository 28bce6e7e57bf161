"""The TD family against Sutton & Barto's published results (Figures 6.2, 6.4, 6.5) and
against exact optima (FrozenLake 4x4)."""

import numpy as np
import pytest

import policylab as pl
from policylab import tabular as tab


def _rms_after(study, truth):
    return float(np.sqrt(((study.v - truth)[:, 1:-1] ** 2).mean(axis=1)).mean())


def test_figure_6_2_td_beats_constant_alpha_mc_on_the_random_walk():
    """Example 6.2: 100 runs of 100 episodes from V = 0.5. TD(0) approaches 1/6..5/6 and
    its RMS error (averaged over states, then runs) ends below that of constant-alpha MC
    at every alpha of the figure (MC = n-step TD with n beyond any episode)."""
    mdp = pl.problems.random_walk()
    truth = pl.problems.random_walk_true_values()
    td = {
        a: _rms_after(
            tab.seed_study("td0", mdp, 100, seed=0, episodes=100, alpha=a, init=0.5), truth
        )
        for a in (0.05, 0.1, 0.15)
    }
    mc = {
        a: _rms_after(
            tab.seed_study(
                "n-step-td", mdp, 100, seed=0, episodes=100, alpha=a, init=0.5, n=100_000
            ),
            truth,
        )
        for a in (0.01, 0.02, 0.03, 0.04)
    }
    assert max(td.values()) < min(mc.values())
    assert td[0.05] < 0.05  # approaches the true values
    # The estimates themselves, averaged over runs, are near 1/6 .. 5/6.
    study = tab.seed_study("td0", mdp, 100, seed=1, episodes=100, alpha=0.05, init=0.5)
    np.testing.assert_allclose(study.v.mean(axis=0)[1:6], truth[1:6], atol=0.03)


def test_figure_6_2_error_curve_decreases():
    mdp = pl.problems.random_walk()
    res = tab.td0(mdp, episodes=100, alpha=0.05, init=0.5, seed=0, checkpoints=100)
    assert res.error_target == "v_pi"
    assert res.checkpoints[-1] == 100
    assert res.error_rms[-1] < res.error_rms[0]


def test_figure_6_4_cliff_walking_sarsa_safe_q_learning_optimal():
    """epsilon = 0.1, alpha = 0.5: mean reward per episode over episodes 101-500,
    averaged over runs, is about -29 for Sarsa (safe path) and -50 for Q-learning
    (optimal path, with falls from exploration)."""
    mdp = pl.problems.cliff_walking()
    sarsa = tab.seed_study("sarsa", mdp, 50, seed=0, episodes=500, alpha=0.5, epsilon=0.1)
    qlearn = tab.seed_study("q-learning", mdp, 50, seed=0, episodes=500, alpha=0.5, epsilon=0.1)
    assert sarsa.mean_return(100) == pytest.approx(-29, abs=2.5)
    assert qlearn.mean_return(100) == pytest.approx(-50, abs=2.5)
    # Figure 6.3: Expected Sarsa does better than Sarsa at this alpha.
    expected = tab.seed_study(
        "expected-sarsa", mdp, 50, seed=0, episodes=500, alpha=0.5, epsilon=0.1
    )
    assert expected.mean_return(100) > sarsa.mean_return(100) + 3
    # Q-learning's greedy policy is the optimal 13-step path along the cliff.
    res = tab.q_learning(mdp, episodes=500, alpha=0.5, epsilon=0.1, seed=0)
    ep = pl.rollout(mdp, res.to_policy(), seed=0, max_steps=100)
    assert ep.ret(1.0) == -13.0


def test_figure_6_5_double_q_learning_removes_the_maximization_bias():
    """Example 6.7 (alpha = 0.1, epsilon = 0.1, 1000 runs of 300 episodes): Q-learning
    goes left far more often than the optimal 5% and overestimates q(A, left) = -0.1;
    Double Q-learning stays near 5%."""
    mdp = pl.problems.maximization_bias()
    left = mdp.action_index("left")
    kw = dict(seed=0, episodes=300, alpha=0.1, epsilon=0.1)
    q = tab.seed_study("q-learning", mdp, 1000, **kw)
    dq = tab.seed_study("double-q-learning", mdp, 1000, **kw)
    q_left = (q.first_actions == left).mean(axis=0)
    dq_left = (dq.first_actions == left).mean(axis=0)
    assert q_left[:100].mean() > 0.5
    assert dq_left[:100].mean() < 0.5 * q_left[:100].mean()
    assert dq_left[-50:].mean() == pytest.approx(0.05, abs=0.03)
    assert dq_left.mean() < q_left.mean() - 0.2
    # The bias itself: Q-learning's estimate of q(A, left) after 300 episodes is above
    # Double Q's, which is near the true -0.1.
    a = mdp.state_index("A")
    assert q.q[:, a, left].mean() > dq.q[:, a, left].mean()
    assert dq.q[:, a, left].mean() == pytest.approx(-0.1, abs=0.08)


@pytest.mark.parametrize("learner", [tab.q_learning, tab.sarsa])
def test_frozenlake_4x4_exact_optimal_policy_with_decaying_schedules(learner):
    """FrozenLake 4x4 (slippery, gamma = 0.95): with epsilon decaying exponentially and
    alpha = 1/n^0.6 the greedy policy is optimal in every state (checked against q* by
    value iteration), for several seeds."""
    mdp = pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=0.95)
    for seed in range(3):
        res = learner(
            mdp,
            episodes=30_000,
            alpha="inverse:1,0.6,0",
            epsilon="exp:1,0.9995,0.01",
            seed=seed,
            checkpoints=2,
        )
        assert res.error_target == "q*"
        assert res.error["optimal_actions"] == 1.0, (learner.__name__, seed)
        v_greedy = pl.evaluate_policy(mdp, res.to_policy())
        np.testing.assert_allclose(v_greedy, pl.value_iteration(mdp, tol=1e-12).v, atol=1e-8)


def _best_epsilon_soft_length(mdp, eps):
    """Expected episode length of the best epsilon-soft policy: policy iteration over
    epsilon-greedy policies with exact evaluation (a linear solve per step)."""
    S, A = mdp.n_states, mdp.n_actions
    q = pl.value_iteration(mdp, tol=1e-10).q
    for _ in range(20):
        best = np.argmax(np.where(mdp.action_mask, q, -np.inf), axis=1)
        probs = np.where(mdp.action_mask, eps / A, 0.0)
        probs[np.arange(S), best] += 1 - eps
        probs[mdp.terminal] = 0.0
        v = pl.evaluate_policy(mdp, pl.Policy.from_array(mdp, probs))
        q = pl.action_values(mdp, v)
    return -v[mdp.state_index((3, 0))]


def test_windy_gridworld_figure_6_3():
    """Example 6.5 (epsilon 0.1, alpha 0.5): Sarsa completes about 170 episodes in its
    first 8000 steps (Figure 6.3), its later episodes are a few steps longer than the
    best epsilon-soft policy's 17 (exact), and Q-learning's greedy path is the optimal 15."""
    mdp = pl.problems.windy_gridworld()
    study = tab.seed_study("sarsa", mdp, 20, seed=0, episodes=500, alpha=0.5, epsilon=0.1)
    steps_to_170 = study.lengths[:, :170].sum(axis=1).mean()
    assert steps_to_170 == pytest.approx(8000, rel=0.12)
    best = _best_epsilon_soft_length(mdp, 0.1)
    assert best == pytest.approx(17.05, abs=0.01)
    assert best < study.lengths[:, 400:].mean() < best + 6
    res = tab.q_learning(mdp, episodes=500, alpha=0.5, epsilon=0.1, seed=0)
    ep = pl.rollout(mdp, res.to_policy(), seed=0, max_steps=100)
    assert ep.terminated and len(ep) == 15


def test_dyna_q_learns_faster_than_q_learning_per_episode():
    """Figure 8.2's point: planning steps shorten the episodes of the first episodes."""
    mdp = pl.problems.windy_gridworld()
    kw = dict(seed=0, episodes=30, alpha=0.5, epsilon=0.1)
    plain = tab.seed_study("dyna-q", mdp, 10, planning_steps=0, **kw)
    dyna = tab.seed_study("dyna-q", mdp, 10, planning_steps=20, **kw)
    assert dyna.lengths[:, 1:].sum() < 0.5 * plain.lengths[:, 1:].sum()


def test_sarsa_lambda_and_n_step_sarsa_solve_windy_gridworld():
    mdp = pl.problems.windy_gridworld()
    for res in (
        tab.sarsa_lambda(
            mdp, lam=0.9, trace="replacing", episodes=300, alpha=0.3, epsilon=0.05, seed=0
        ),
        tab.n_step_sarsa(mdp, n=4, episodes=300, alpha=0.3, epsilon=0.05, seed=0),
        tab.expected_sarsa(mdp, episodes=300, alpha=0.5, epsilon=0.05, seed=0),
    ):
        ep = pl.rollout(mdp, res.to_policy(), seed=0, max_steps=100)
        assert ep.terminated and len(ep) <= 17, res


def _walk19_error(algo, alpha, **kw):
    """RMS error over the 19 states, averaged over the first 10 episodes and 100 runs
    (Figures 7.2 and 12.6). Runs with the same seed share their first k episodes, so the
    error after k episodes is that of a k-episode study."""
    mdp = pl.problems.random_walk(19, left_reward=-1.0)
    truth = pl.problems.random_walk_true_values(19, -1.0)
    errs = []
    for k in range(1, 11):
        study = tab.seed_study(algo, mdp, 100, seed=0, episodes=k, alpha=alpha, **kw)
        errs.append(np.sqrt(((study.v - truth)[:, 1:-1] ** 2).mean(axis=1)).mean())
    return float(np.mean(errs))


def test_figure_7_2_intermediate_n_is_best_on_the_19_state_walk():
    """n = 4 (alpha 0.4) beats one-step TD at its best alpha and a long n = 32; its
    error is about the 0.25-0.27 of the book's figure."""
    four = _walk19_error("n-step-td", 0.4, n=4)
    one = _walk19_error("n-step-td", 0.8, n=1)
    long = _walk19_error("n-step-td", 0.1, n=32)
    assert four == pytest.approx(0.26, abs=0.03)
    assert four < one - 0.05 and four < long - 0.05


def test_figure_12_6_td_lambda_beats_td0_on_the_19_state_walk():
    lam = _walk19_error("td-lambda", 0.4, lam=0.8)
    td0 = _walk19_error("td-lambda", 0.8, lam=0.0)
    assert lam < td0 - 0.05
