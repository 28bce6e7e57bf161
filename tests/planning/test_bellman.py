"""One function per Bellman equation: each checked against its definition."""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.planning import (
    bellman_expectation_backup,
    bellman_optimality_backup,
    greedy_actions,
    policy_reward,
    policy_transition_matrix,
    proper_policy,
    state_values,
)

from .conftest import small_random_mdp


def test_backups_by_their_definition() -> None:
    mdp = small_random_mdp(3, 4, 3, 0.8, episodic=True)
    S, A = mdp.n_states, mdp.n_actions
    rng = np.random.default_rng(0)
    v = rng.normal(size=S)
    v[mdp.terminal] = 0
    # q(s, a) = sum_{s', r} p(s', r | s, a) [r + gamma v(s')], from the outcome lists
    q = np.full((S, A), -np.inf)
    for s in range(S):
        for a in range(A):
            if mdp.action_mask[s, a]:
                outs = mdp.outcomes(mdp.states[s], mdp.actions[a])
                q[s, a] = sum(p * (r + 0.8 * v[mdp.state_index(n)]) for p, n, r in outs)
    assert np.allclose(pl.action_values(mdp, v), q)
    expected = np.where(mdp.terminal, 0.0, q.max(axis=1))
    assert np.allclose(bellman_optimality_backup(mdp, v), expected)
    pi = pl.Policy.uniform(mdp)
    t_pi = np.where(mdp.terminal, 0.0, (pi.probs * np.where(mdp.action_mask, q, 0)).sum(axis=1))
    assert np.allclose(bellman_expectation_backup(mdp, v, pi), t_pi)
    assert np.allclose(state_values(mdp, pl.action_values(mdp, v), pi), t_pi)
    P = policy_transition_matrix(mdp, pi).toarray()
    assert np.allclose(P[~mdp.terminal].sum(axis=1), 1.0) and not P[mdp.terminal].any()
    r = policy_reward(mdp, pi)
    assert np.allclose(r, np.einsum("sa,sa->s", pi.probs, mdp.expected_reward))
    acts = greedy_actions(mdp, q)
    assert (acts[mdp.terminal] == -1).all()
    assert np.array_equal(acts[~mdp.terminal], q.argmax(axis=1)[~mdp.terminal])


def test_v_star_is_the_fixed_point_and_v_pi_of_its_policy() -> None:
    mdp = pl.problems.gridworld_5x5()
    res = pl.policy_iteration(mdp)
    assert np.allclose(bellman_optimality_backup(mdp, res.v), res.v, atol=1e-10)
    assert np.allclose(bellman_expectation_backup(mdp, res.v, res.policy), res.v, atol=1e-10)


def test_policies_in_every_accepted_form() -> None:
    robot = pl.problems.recycling_robot()
    expected = pl.evaluate_policy(robot, pl.problems.recycling_robot_deterministic_policy(robot))
    forms = [
        {"high": "search", "low": "recharge"},
        {"high": {"search": 1.0}, "low": {"recharge": 1.0}},
        np.array([0, 2]),
        np.array([[1.0, 0, 0], [0, 0, 1.0]]),
    ]
    for form in forms:
        assert np.allclose(pl.evaluate_policy(robot, form), expected)


def test_proper_policy_reaches_the_end() -> None:
    for mdp in (
        pl.problems.gridworld_4x4(),
        pl.problems.gamblers_problem(),
        pl.problems.mountain_gridworld(),
    ):
        pi = proper_policy(mdp)
        assert np.isfinite(pl.evaluate_policy(mdp, pi)).all()  # gamma = 1 would raise if not
    with pytest.raises(pl.InvalidMDPError, match="continuing task"):
        proper_policy(pl.problems.recycling_robot())
