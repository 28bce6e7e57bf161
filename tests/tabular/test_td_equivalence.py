"""Exact identities of the TD family: special cases that must coincide bit for bit,
hand-computed updates, the two paths, and seeding."""

import numpy as np
import pytest

import policylab as pl
from policylab import tabular as tab
from policylab.tabular import td_kernels as tdk


@pytest.fixture(scope="module")
def cliff():
    return pl.problems.cliff_walking()


@pytest.fixture(scope="module")
def lake():
    return pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=0.95)


def same(a, b):
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.episode_returns, b.episode_returns)
    assert a.steps == b.steps


CONTROL = dict(episodes=60, alpha=0.5, epsilon=0.1, seed=7, checkpoints=3)


@pytest.mark.parametrize("problem", ["cliff", "lake"])
def test_n_step_sarsa_with_n_1_is_sarsa(problem, request):
    mdp = request.getfixturevalue(problem)
    same(tab.n_step_sarsa(mdp, n=1, **CONTROL), tab.sarsa(mdp, **CONTROL))


@pytest.mark.parametrize("trace", ["accumulating", "replacing"])
@pytest.mark.parametrize("problem", ["cliff", "lake"])
def test_sarsa_lambda_with_lambda_0_is_sarsa(problem, trace, request):
    mdp = request.getfixturevalue(problem)
    same(tab.sarsa_lambda(mdp, lam=0.0, trace=trace, **CONTROL), tab.sarsa(mdp, **CONTROL))


def test_dyna_q_without_planning_is_q_learning(lake):
    same(tab.dyna_q(lake, planning_steps=0, **CONTROL), tab.q_learning(lake, **CONTROL))


PREDICTION = dict(episodes=40, alpha=0.1, init=0.5, seed=3, checkpoints=3)


def test_n_step_td_with_n_1_is_td0():
    mdp = pl.problems.random_walk()
    same(tab.n_step_td(mdp, n=1, **PREDICTION), tab.td0(mdp, **PREDICTION))


@pytest.mark.parametrize("trace", ["accumulating", "replacing"])
def test_td_lambda_with_lambda_0_is_td0(trace):
    mdp = pl.problems.random_walk()
    same(tab.td_lambda(mdp, lam=0.0, trace=trace, **PREDICTION), tab.td0(mdp, **PREDICTION))


def test_n_step_td_with_long_n_is_constant_alpha_monte_carlo():
    """n >= T: the n-step return is the full return, so n-step TD is every-visit
    constant-alpha MC, the shared Monte Carlo learner's answer to the last bit."""
    mdp = pl.problems.random_walk()
    from policylab.tabular.mc import mc_prediction

    mc = mc_prediction(mdp, episodes=50, alpha=0.03, first_visit=False, seed=4, error_on="v")
    td = tab.n_step_td(mdp, n=10_000, episodes=50, alpha=0.03, seed=4)
    np.testing.assert_allclose(td.v, mc.v, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(td.episode_returns, mc.episode_returns)


def test_td0_first_episode_by_hand():
    """alpha = 1 on the random walk: each update copies the target, so after one episode
    every visited state except the last holds the value of its successor at that time."""
    mdp = pl.problems.random_walk()
    res = tab.td0(mdp, episodes=1, alpha=1.0, init=0.5, seed=11, checkpoints=1)
    v = res.v
    last_reward = res.episode_returns[0]
    # The last state before termination copied the terminal reward.
    if last_reward == 1.0:
        assert v[mdp.state_index("E")] == 1.0
    else:
        assert v[mdp.state_index("A")] == 0.0
    assert set(np.round(v[1:6], 12)) <= {0.0, 0.5, 1.0}


def test_q_learning_greedy_episode_by_hand():
    """Deterministic chain, alpha = 1, epsilon = 0: Q(s, a) after k episodes is the
    hand-computed Bellman backup along the path."""
    mdp = pl.FiniteMDP.from_dynamics(
        {"s0": {"go": [(1.0, "s1", 1.0)]}, "s1": {"go": [(1.0, "end", 2.0)]}},
        gamma=0.5,
        terminal=["end"],
        initial="s0",
    )
    res = tab.q_learning(mdp, episodes=1, alpha=1.0, epsilon=0.0, seed=0, checkpoints=1)
    np.testing.assert_array_equal(res.q[:, 0], [1.0, 2.0, 0.0])  # Q(s0) used Q(s1) = 0
    res = tab.q_learning(mdp, episodes=2, alpha=1.0, epsilon=0.0, seed=0, checkpoints=1)
    np.testing.assert_array_equal(res.q[:, 0], [1.0 + 0.5 * 2.0, 2.0, 0.0])
    assert res.error["max"] == 0.0
    res = tab.expected_sarsa(mdp, episodes=2, alpha=1.0, epsilon=0.0, seed=0, checkpoints=1)
    np.testing.assert_array_equal(res.q[:, 0], [2.0, 2.0, 0.0])
    res = tab.n_step_sarsa(mdp, n=2, episodes=1, alpha=1.0, epsilon=0.0, seed=0, checkpoints=1)
    np.testing.assert_array_equal(res.q[:, 0], [1.0 + 0.5 * 2.0, 2.0, 0.0])


def test_update_rules_by_hand():
    q = np.array([1.0, 3.0, 2.0])
    mask = np.array([True, False, True])
    assert tdk.td_update(1.0, 0.25, 3.0) == 1.5
    assert tdk.td_target(1.0, 0.5, 4.0, False) == 3.0
    assert tdk.td_target(1.0, 0.5, 4.0, True) == 1.0
    assert tdk.q_learning_target(0.0, 1.0, q, mask, False) == 2.0  # 3.0 is unavailable
    # epsilon-greedy over {0, 2}: 0.9 + 0.05 on action 2, 0.05 on action 0.
    assert tdk.expected_sarsa_target(0.0, 1.0, q, mask, 0.1, False) == pytest.approx(
        0.95 * 2 + 0.05 * 1
    )
    assert tdk.double_q_target(0.0, 1.0, np.array([0.0, 9.0, 5.0]), q, mask, False) == 2.0
    g, disc = tdk.n_step_return(np.array([9.0, 1.0, 2.0, 4.0]), 0, 3, 0.5)
    assert (g, disc) == (1.0 + 0.5 * 2.0 + 0.25 * 4.0, 0.125)


ALGOS = [
    ("td0", {}),
    ("n-step-td", {"n": 3}),
    ("td-lambda", {"lam": 0.7}),
    ("sarsa", {}),
    ("q-learning", {}),
    ("expected-sarsa", {}),
    ("double-q-learning", {}),
    ("n-step-sarsa", {"n": 3}),
    ("sarsa-lambda", {"lam": 0.7, "trace": "replacing"}),
    ("dyna-q", {"planning_steps": 3}),
]


def _learner(name):
    return getattr(tab, name.replace("-", "_"))


@pytest.mark.parametrize(("name", "opts"), ALGOS)
def test_compiled_and_gymnasium_paths_agree_exactly(name, opts, cliff):
    """One kernel source, two paths: on a deterministic MDP (cliff walking) the Python
    loop over policylab's Gymnasium env gives the compiled kernel's numbers exactly."""
    kw = dict(episodes=15, alpha=0.5, seed=5, checkpoints=2, **opts)
    if name not in ("td0", "n-step-td", "td-lambda"):
        kw["epsilon"] = 0.2
    fast = _learner(name)(cliff, **kw)
    slow = _learner(name)(pl.MDPEnv(cliff), **kw)
    assert fast.params["path"] == "compiled" and slow.params["path"] == "gymnasium"
    same(fast, slow)
    np.testing.assert_array_equal(fast.error_rms, slow.error_rms)


@pytest.mark.parametrize(("name", "opts"), ALGOS)
def test_seeded_runs_are_identical(name, opts, lake):
    kw = dict(episodes=30, seed=123, checkpoints=2, **opts)
    a, b = _learner(name)(lake, **kw), _learner(name)(lake, **kw)
    same(a, b)
    c = _learner(name)(lake, **{**kw, "seed": 124})
    assert a.steps != c.steps or not np.array_equal(a.q, c.q) or not np.array_equal(a.v, c.v)


def test_seed_study_matches_single_runs_and_is_reproducible(cliff):
    study = tab.seed_study("sarsa", cliff, 4, seed=9, episodes=20, alpha=0.5)
    again = tab.seed_study("sarsa", cliff, 4, seed=9, episodes=20, alpha=0.5)
    np.testing.assert_array_equal(study.returns, again.returns)
    np.testing.assert_array_equal(study.q, again.q)
    assert study.returns.shape == (4, 20)
    assert study.steps == int(study.lengths.sum())
    assert len({tuple(r) for r in study.returns}) > 1  # the runs differ


def test_returns_and_steps_bookkeeping(cliff):
    res = tab.sarsa(cliff, episodes=25, alpha=0.5, seed=1)
    assert len(res.episode_returns) == 25
    # gamma = 1 and -1 per step (-100 off the cliff): the return bounds the step count.
    assert res.steps >= -res.episode_returns.sum() / 100
    assert np.all(res.episode_returns <= -13)


def test_shared_run_seeds_runs_td_learners_on_threads(cliff):
    """The shared ``run_seeds`` (threads; the TD kernels release the GIL) gives each
    seed's own run."""
    results = tab.run_seeds(tab.q_learning, cliff, [1, 2, 3], episodes=40, alpha=0.5, workers=2)
    for seed, res in zip([1, 2, 3], results, strict=True):
        same(res, tab.q_learning(cliff, episodes=40, alpha=0.5, seed=seed))
