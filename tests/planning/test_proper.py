"""gamma = 1: every solver returns a policy that is optimal and proper (it terminates).

A zero-reward self-loop ties with the move toward the goal; a solver that takes the
lowest-index tied action may then return a policy that never ends an episode.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import policylab as pl
from policylab.exceptions import InvalidMDPError
from policylab.planning import (
    greedy_actions,
    linear_programming,
    modified_policy_iteration,
    optimal_actions,
    proper_actions,
    relative_value_iteration,
)

from .conftest import small_random_mdp


def _solvers(mdp: pl.FiniteMDP) -> list[pl.planning.PlanningResult]:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return [
            pl.value_iteration(mdp, tol=1e-12),
            pl.value_iteration(mdp, tol=1e-12, gauss_seidel=True),
            modified_policy_iteration(mdp, tol=1e-12),
            modified_policy_iteration(mdp, tol=1e-12, m=0),
            linear_programming(mdp),
            pl.policy_iteration(mdp),
            pl.policy_iteration(mdp, evaluation="iterative", tol=1e-12),
        ]


def stay_or_go() -> pl.FiniteMDP:
    return pl.FiniteMDP.from_dynamics(
        {0: {"stay": [(1.0, 0, 0.0)], "go": [(1.0, 1, 1.0)]}, 1: {}},
        gamma=1.0,
        terminal=(1,),
    )


def test_stay_or_go_every_solver_goes() -> None:
    mdp = stay_or_go()
    for res in _solvers(mdp):
        assert res.policy.to_dict() == {"0": {"go": 1.0}} or res.policy.action_indices()[0] == 1
        assert pl.evaluate_policy(mdp, res.policy)[0] == pytest.approx(1.0), res.method
    q = pl.action_values(mdp, [1.0, 0.0])
    # Both actions are optimal; only "go" ends the episode.
    assert optimal_actions(mdp, q)[0].tolist() == [True, True]
    assert optimal_actions(mdp, q, proper=True)[0].tolist() == [False, True]
    assert greedy_actions(mdp, q)[0] == 0
    assert greedy_actions(mdp, q, proper=True)[0] == 1
    assert pl.greedy_policy(mdp, q).action_indices()[0] == 0
    assert pl.greedy_policy(mdp, q, proper=True).action_indices()[0] == 1
    uni = pl.greedy_policy(mdp, q, ties="uniform", proper=True)
    assert uni.probs[0].tolist() == [0.0, 1.0]


def test_frozenlake_deterministic_gamma_one_policies_reach_the_goal() -> None:
    env = gym.make("FrozenLake-v1", is_slippery=False)
    mdp = pl.FiniteMDP.from_gymnasium(env, gamma=1.0)
    env.close()
    # Every non-hole state can reach the goal: v_* = 1 there, 0 in the holes.
    v_star = np.where(mdp.terminal, 0.0, 1.0)
    for res in _solvers(mdp):
        assert np.allclose(res.v, v_star, atol=1e-7), res.method
        # Exact evaluation raises if the policy loops forever somewhere.
        assert np.allclose(pl.evaluate_policy(mdp, res.policy), v_star, atol=1e-9), res.method
        assert res.policy.action_indices()[0] in (1, 2)  # down or right, not left


def episodic_with_loops(seed: int, n: int, n_actions: int) -> pl.FiniteMDP:
    """Live states 0..n-1 and terminal n; rewards only on entering the terminal state (>= 0).

    Action 0 is a zero-reward self-loop in every state, so it ties with the best action
    wherever the optimum is reached by moving; the other actions move at random (some
    deterministically), and state 0 .. n-1 can always reach the end through action 1.
    """
    rng = np.random.default_rng(seed)
    S, A = n + 1, n_actions + 1
    P = np.zeros((A, S, S))
    R = np.zeros((A, S, S))
    P[0, np.arange(S), np.arange(S)] = 1.0
    for a in range(1, A):
        for s in range(n):
            if rng.random() < 0.5:  # deterministic move
                P[a, s, rng.integers(0, S)] = 1.0
            else:
                k = int(rng.integers(1, min(3, S) + 1))
                P[a, s, rng.choice(S, size=k, replace=False)] = rng.random(k) + 0.1
        P[a, n, n] = 1.0
    P[1, np.arange(n), :] = 0.0
    P[1, np.arange(n), np.arange(1, n + 1)] = 1.0  # a path s -> s + 1 -> ... -> end
    P /= P.sum(axis=2, keepdims=True)
    R[:, :, n] = rng.integers(0, 3, size=(A, S)).astype(float)  # ties on purpose
    R[0] = 0.0
    return pl.FiniteMDP.from_arrays(P, R, gamma=1.0, terminal=[n])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 6), st.integers(1, 3))
def test_random_episodic_policies_are_proper_and_optimal(seed: int, n: int, n_act: int) -> None:
    mdp = episodic_with_loops(seed, n, n_act)
    v_star = linear_programming(mdp).v
    for res in _solvers(mdp):
        v_pi = pl.evaluate_policy(mdp, res.policy)  # raises if improper
        assert np.allclose(v_pi, v_star, atol=1e-6), res.method
    q = pl.action_values(mdp, pl.policy_iteration(mdp).v)
    for ties in ("first", "uniform"):
        pi = pl.greedy_policy(mdp, q, ties=ties, proper=True)
        assert np.allclose(pl.evaluate_policy(mdp, pi), v_star, atol=1e-6)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 5), st.integers(1, 3))
def test_proper_actions_of_all_actions_form_a_proper_policy(seed: int, n: int, a: int) -> None:
    mdp = small_random_mdp(seed, n, a, 1.0, episodic=True)
    mask = proper_actions(mdp, mdp.action_mask)
    live = ~mdp.terminal
    assert mask[live].any(axis=1).all()
    assert not (mask & ~mdp.action_mask).any()
    probs = mask / np.maximum(mask.sum(axis=1, keepdims=True), 1)
    pl.evaluate_policy(mdp, pl.Policy.from_array(mdp, probs))  # proper: no error


def test_states_with_no_optimal_way_out_keep_their_optimal_actions() -> None:
    # From state 0 the only way to the end costs -1; staying forever costs 0, so no
    # optimal policy is proper there: the optimal (looping) action is kept.
    mdp = pl.FiniteMDP.from_dynamics(
        {0: {"stay": [(1.0, 0, 0.0)], "go": [(1.0, 1, -1.0)]}, 1: {}},
        gamma=1.0,
        terminal=(1,),
    )
    q = pl.action_values(mdp, [0.0, 0.0])
    assert optimal_actions(mdp, q, proper=True)[0].tolist() == [True, False]


def test_relative_value_iteration_reports_a_multichain_mdp() -> None:
    # Every action absorbing: state 0 earns 1 per step forever, state 1 earns 2.
    mdp = pl.FiniteMDP.from_dynamics(
        {
            0: {"a": [(1.0, 0, 1.0)], "b": [(1.0, 0, 0.5)]},
            1: {"a": [(1.0, 1, 2.0)], "b": [(1.0, 1, 0.0)]},
        },
        gamma=1.0,
    )
    with pytest.raises(InvalidMDPError, match="gain differs by state") as err:
        relative_value_iteration(mdp, max_iter=1000)
    assert "multichain" in str(err.value)
    # A transient state choosing between two absorbing states of different gains.
    mdp3 = pl.FiniteMDP.from_dynamics(
        {
            0: {"left": [(1.0, 1, 0.0)], "right": [(0.5, 2, 0.0), (0.5, 0, 0.0)]},
            1: {"left": [(1.0, 1, 1.0)], "right": [(1.0, 1, 1.0)]},
            2: {"left": [(1.0, 2, 3.0)], "right": [(1.0, 2, 3.0)]},
        },
        gamma=1.0,
    )
    with pytest.raises(InvalidMDPError, match="gain differs by state"):
        relative_value_iteration(mdp3, max_iter=1000)


def test_relative_value_iteration_still_solves_unichain_mdps() -> None:
    res = relative_value_iteration(pl.problems.random_mdp(60, 3, 4, seed=1))
    assert res.converged and res.error_bound is not None and res.error_bound <= 1e-8


def test_proper_policy_raises_when_no_terminal_is_reachable() -> None:
    with pytest.raises(InvalidMDPError):
        pl.planning.proper_policy(pl.problems.recycling_robot())
