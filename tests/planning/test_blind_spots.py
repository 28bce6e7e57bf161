"""The Bellman backups treat terminal states as v = 0, whatever the given v holds there.

The notes define v(s) = 0 for every terminal s (S+ minus S): a backup reads v only through
sum_{s'} p(s' | s, a) v(s'), and a terminal successor contributes 0. So a value array that
holds garbage on its terminal entries must back up exactly as the one with zeros there.
"""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.planning import (
    action_values,
    bellman_expectation_backup,
    bellman_optimality_backup,
)

from .conftest import small_random_mdp


def two_state_chain() -> pl.FiniteMDP:
    """start --(reward 1)--> end, end terminal."""
    return pl.FiniteMDP.from_dynamics(
        {"start": {"go": [(1.0, "end", 1.0)]}}, gamma=0.9, terminal=("end",)
    )


def test_expectation_backup_ignores_the_value_held_on_a_terminal_state():
    mdp = two_state_chain()
    pi = pl.Policy.uniform(mdp)
    # (T_pi v)(start) = 1 + gamma * v(end) with v(end) = 0 by definition; (T_pi v)(end) = 0.
    np.testing.assert_allclose(bellman_expectation_backup(mdp, [0.0, 5.0], pi), [1.0, 0.0])
    np.testing.assert_allclose(bellman_optimality_backup(mdp, [0.0, 5.0]), [1.0, 0.0])
    np.testing.assert_allclose(action_values(mdp, [0.0, 5.0])[0], [1.0])


@pytest.mark.parametrize("seed", range(4))
def test_backups_are_blind_to_terminal_entries_on_random_episodic_mdps(seed):
    mdp = small_random_mdp(seed, n_states=5, n_actions=3, gamma=0.95, episodic=True)
    rng = np.random.default_rng(seed)
    v = rng.normal(size=mdp.n_states)
    v_clean = np.where(mdp.terminal, 0.0, v)
    v_dirty = np.where(mdp.terminal, rng.normal(10.0, 3.0, size=mdp.n_states), v)
    probs = rng.random((mdp.n_states, mdp.n_actions)) * mdp.action_mask
    probs[mdp.terminal] = 0.0
    probs[~mdp.terminal] /= probs[~mdp.terminal].sum(axis=1, keepdims=True)
    pi = pl.Policy.from_array(mdp, probs)

    np.testing.assert_array_equal(
        bellman_expectation_backup(mdp, v_dirty, pi), bellman_expectation_backup(mdp, v_clean, pi)
    )
    np.testing.assert_array_equal(
        bellman_optimality_backup(mdp, v_dirty), bellman_optimality_backup(mdp, v_clean)
    )
    # Terminal states back up to 0, and v_pi stays the fixed point of T_pi even when the
    # terminal entries are overwritten.
    v_pi = pl.evaluate_policy(mdp, pi)
    assert np.all(bellman_expectation_backup(mdp, v_dirty, pi)[mdp.terminal] == 0.0)
    np.testing.assert_allclose(
        bellman_expectation_backup(mdp, np.where(mdp.terminal, 7.0, v_pi), pi), v_pi, atol=1e-10
    )


# ----------------------------------------------------------------------------- stopping rules
def self_loop(gamma: float) -> pl.FiniteMDP:
    """One state that pays 1 and stays: v_* = 1 / (1 - gamma), and each sweep of value
    iteration moves v by exactly gamma / (1 - gamma) times its last change short of v_*."""
    return pl.FiniteMDP.from_dynamics({"s": {"stay": [(1.0, "s", 1.0)]}}, gamma=gamma)


def chain() -> pl.FiniteMDP:
    """s0 -> s1 -> end, reward 1 per step: v_* = [1 + gamma, 1, 0]."""
    return pl.FiniteMDP.from_dynamics(
        {"s0": {"go": [(1.0, "s1", 1.0)]}, "s1": {"go": [(1.0, "end", 1.0)]}},
        gamma=0.9,
        terminal=("end",),
    )


@pytest.mark.parametrize("gauss_seidel", [False, True])
@pytest.mark.parametrize("tol", [1e-2, 1e-5])
def test_value_iteration_meets_its_tolerance_where_the_bound_is_tight(gauss_seidel, tol):
    """tol bounds max_s |v(s) - v_*(s)| (the documented guarantee), also on the self-loop,
    where a rule that stops on the last change alone misses by gamma / (1 - gamma)."""
    mdp = self_loop(0.99)
    res = pl.value_iteration(mdp, tol=tol, gauss_seidel=gauss_seidel)
    assert res.converged
    assert abs(res.v[0] - 100.0) <= tol
    # The bound is tight here: equal to the error up to rounding.
    assert res.error_bound is not None and res.error_bound <= tol
    assert abs(res.v[0] - 100.0) <= res.error_bound + 1e-12


@pytest.mark.parametrize("gauss_seidel", [False, True])
@pytest.mark.parametrize("shift", [-50.0, 50.0])
def test_value_iteration_meets_its_tolerance_from_any_start(gauss_seidel, shift):
    """From v0 above v_* the values fall: the change |T v - v| must count decreases too."""
    mdp = small_random_mdp(3, n_states=6, n_actions=3, gamma=0.9)
    v_star = pl.policy_iteration(mdp).v
    res = pl.value_iteration(mdp, tol=1e-6, gauss_seidel=gauss_seidel, v0=v_star + shift)
    np.testing.assert_allclose(res.v, v_star, rtol=0, atol=1e-6)


def test_value_iteration_bound_counts_the_zero_change_of_terminal_states():
    """From v0 = 0 on the chain, the first sweep changes both live states by 1: without
    d(end) = 0 in the span the bound would read 0 and stop at a wrong v."""
    mdp = chain()
    res = pl.value_iteration(mdp, tol=1e-8)
    np.testing.assert_allclose(res.v, [1.9, 1.0, 0.0], rtol=0, atol=1e-8)
    assert res.iterations > 1


# ----------------------------------------------------------------------------- ties
def test_ties_are_within_tol_times_max_of_1_and_the_best_value():
    """a is greedy when q(s, a) >= max q - tol * max(1, |max q|): near 0 the tolerance is
    absolute, far from 0 relative."""
    from policylab.planning import optimal_actions

    mdp = pl.FiniteMDP.from_dynamics(
        {"s": {"a": [(1.0, "end", 0.0)], "b": [(1.0, "end", 0.0)]}}, gamma=0.9, terminal=("end",)
    )
    near_zero = np.array([[0.0, -5e-10], [0.0, 0.0]])
    assert optimal_actions(mdp, near_zero)[0].tolist() == [True, True]
    assert optimal_actions(mdp, np.array([[0.0, -2e-9], [0.0, 0.0]]))[0].tolist() == [True, False]
    big = np.array([[1e6, 1e6 - 5e-4], [0.0, 0.0]])
    assert optimal_actions(mdp, big)[0].tolist() == [True, True]
    assert optimal_actions(mdp, np.array([[1e6, 1e6 - 2e-3], [0.0, 0.0]]))[0].tolist() == [
        True,
        False,
    ]


def test_policy_iteration_keeps_a_current_action_that_ties_the_best():
    """Improvement changes pi(s) only for a strictly better action (within tie_tol), so a
    policy that already takes an optimal action is left as it is: no cycling on ties."""
    mdp = pl.FiniteMDP.from_dynamics(
        {"s": {"a": [(1.0, "end", 1.0)], "b": [(1.0, "end", 1.0)], "c": [(1.0, "end", 0.0)]}},
        gamma=0.9,
        terminal=("end",),
    )
    for start in ("a", "b"):
        res = pl.policy_iteration(mdp, policy=pl.Policy.deterministic(mdp, {"s": start}))
        assert res.policy.probs[0].tolist() == [float(start == "a"), float(start == "b"), 0.0]
    res = pl.policy_iteration(mdp, policy=pl.Policy.deterministic(mdp, {"s": "c"}))
    assert res.policy.probs[0].tolist() == [1.0, 0.0, 0.0]  # the first of the tied best
