"""Rollouts: the sequence S0, A0, R1, ..., returns, seeding."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl


def test_rollout_sequence_and_returns_on_the_bad_policy():
    mdp = pl.problems.mountain_gridworld()
    pi = pl.problems.mountain_gridworld_bad_policy(mdp)
    ep = pl.rollout(mdp, pi, seed=0)
    assert ep.terminated and not ep.truncated
    assert ep.sequence() == [
        (2, 0),
        "right",
        -1.0,
        (2, 1),
        "up",
        -3.0,
        (1, 1),
        "up",
        -3.0,
        (0, 1),
        "right",
        -1.0,
        (0, 2),
        "down",
        -3.0,
        (1, 2),
        "down",
        5.0,
        (2, 2),
    ]
    assert ep.ret(1.0) == -6.0
    np.testing.assert_allclose(ep.returns(1.0), [-6, -5, -2, 1, 2, 5])
    assert pl.rollout(mdp, pi, seed=0, start=(2, 1)).ret(1.0) == -5.0


def test_rollout_seeded_identical_and_different_seeds_differ():
    mdp = pl.problems.slippery_gridworld()
    pi = pl.Policy.uniform(mdp)
    a, b = pl.rollout(mdp, pi, seed=11), pl.rollout(mdp, pi, seed=11)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.rewards, b.rewards)
    eps = [pl.rollout(mdp, pi, seed=s) for s in range(20)]
    assert len({tuple(e.states) for e in eps}) > 1


def test_rollout_on_a_gymnasium_env_is_seeded():
    pi = pl.Policy.uniform(pl.problems.slippery_gridworld())
    env = gym.make("policylab/SlipperyGridworld-v0")
    a, b = pl.rollout(env, pi, seed=5), pl.rollout(env, pi, seed=5)
    np.testing.assert_array_equal(a.states, b.states)
    assert a.terminated and a.rewards[-1] == 10.0
    assert a.sequence()[0] == 1


def test_rollout_truncates_continuing_task():
    mdp = pl.problems.recycling_robot()
    ep = pl.rollout(
        mdp, pl.problems.recycling_robot_deterministic_policy(mdp), seed=0, max_steps=50
    )
    assert ep.truncated and not ep.terminated and len(ep) == 50
    assert len(ep.states) == 51


def test_rollout_with_callable_policy_on_frozenlake():
    env = gym.make("FrozenLake-v1")
    ep = pl.rollout(env, lambda obs: 2, seed=0, max_steps=100)
    assert len(ep.states) == len(ep.actions) + 1


def test_mc_estimate_of_the_random_policy_agrees_with_sampled_returns():
    # E[G_0] of the uniform policy on the mountain gridworld from S, by the linear solve
    mdp = pl.problems.mountain_gridworld()
    pi = pl.Policy.uniform(mdp)
    S = mdp.n_states
    P = mdp.transition_matrix.toarray().reshape(S, 4, S)
    Ppi = np.einsum("sa,sat->st", pi.probs, P)
    r = (pi.probs * mdp.expected_reward).sum(1)
    live = ~mdp.terminal
    v = np.zeros(S)
    v[live] = np.linalg.solve(np.eye(live.sum()) - Ppi[np.ix_(live, live)], r[live])
    rng = np.random.default_rng(0)
    gs = np.array([pl.rollout(mdp, pi, seed=rng).ret(1.0) for _ in range(3000)])
    start = mdp.state_index((2, 0))
    # within 4 standard errors of the exact value (fails by chance with p < 1e-4)
    assert abs(gs.mean() - v[start]) < 4 * gs.std(ddof=1) / np.sqrt(len(gs))


def test_bad_max_steps():
    mdp = pl.problems.slippery_gridworld()
    with pytest.raises(pl.InvalidArgumentError, match="max_steps"):
        pl.rollout(mdp, pl.Policy.uniform(mdp), max_steps=0)


def test_rollout_refuses_a_policy_of_another_mdp():
    grid = pl.problems.mountain_gridworld()
    other = pl.problems.recycling_robot()
    with pytest.raises(pl.exceptions.InvalidPolicyError, match="built for another MDP"):
        pl.rollout(grid, pl.Policy.uniform(other), seed=0)
    env = pl.envs.MDPEnv(grid)
    with pytest.raises(pl.exceptions.InvalidPolicyError, match="built for another MDP"):
        pl.rollout(env, pl.Policy.uniform(other), seed=0)
    lake = gym.make("FrozenLake-v1")
    with pytest.raises(pl.exceptions.InvalidPolicyError, match="has 2 states"):
        pl.rollout(lake, pl.Policy.uniform(other), seed=0)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"seed": -1}, "seed must be a non-negative integer"),
        ({"seed": 1.5}, "seed must be an integer"),
        ({"max_steps": 0}, "max_steps"),
        ({"max_steps": 2.5}, "max_steps"),
    ],
)
def test_rollout_bad_arguments_are_policylab_errors(kwargs, words):
    mdp = pl.problems.recycling_robot()
    with pytest.raises(pl.exceptions.InvalidArgumentError, match=words):
        pl.rollout(mdp, pl.Policy.uniform(mdp), **kwargs)


def test_rollout_checks_what_a_policy_function_returns():
    mdp = pl.problems.recycling_robot()
    with pytest.raises(pl.exceptions.InvalidActionError, match="expected 0..2"):
        pl.rollout(mdp, lambda s: 7, seed=0)
    with pytest.raises(pl.exceptions.InvalidActionError, match="an integer"):
        pl.rollout(mdp, lambda s: "search", seed=0)
