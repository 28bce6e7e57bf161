"""Backward induction and relative value iteration against brute-force oracles."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError, InvalidMDPError, NotConvergedWarning
from policylab.planning import backward_induction, relative_value_iteration

from .conftest import small_random_mdp


@pytest.mark.parametrize("seed", range(5))
def test_backward_induction_matches_expectimax_recursion(seed: int) -> None:
    mdp = small_random_mdp(seed, 3, 2, 0.9, episodic=seed % 2 == 0)
    S, A = mdp.n_states, mdp.n_actions
    T = mdp.transition_matrix.toarray().reshape(S, A, S)
    R = mdp.expected_reward
    salvage = np.arange(S, dtype=float)
    salvage[mdp.terminal] = 0.0

    def value(s: int, steps: int) -> float:  # plain recursion, no vectors
        if steps == 0 or mdp.terminal[s]:
            return 0.0 if mdp.terminal[s] else salvage[s]
        return max(
            R[s, a] + 0.9 * sum(T[s, a, t] * value(t, steps - 1) for t in range(S) if T[s, a, t])
            for a in range(A)
            if mdp.action_mask[s, a]
        )

    res = backward_induction(mdp, 4, terminal_values=salvage)
    assert res.stage_values is not None and res.stage_actions is not None
    for t in range(5):
        assert res.stage_values[t] == pytest.approx([value(s, 4 - t) for s in range(S)])
    assert res.v == pytest.approx(res.stage_values[0])
    assert res.stage_actions.shape == (4, S)


def _gain(mdp: pl.FiniteMDP, acts: tuple[int, ...]) -> np.ndarray:
    S, A = mdp.n_states, mdp.n_actions
    T = mdp.transition_matrix.toarray().reshape(S, A, S)
    P = T[np.arange(S), list(acts)]
    r = mdp.expected_reward[np.arange(S), list(acts)]
    # Cesaro limit of P^n r, by a long average (chains here are aperiodic: all entries > 0)
    x = np.linalg.matrix_power(P, 2000) @ r
    return x


@pytest.mark.parametrize("seed", range(4))
def test_relative_value_iteration_finds_the_best_gain(seed: int) -> None:
    mdp = small_random_mdp(seed, 4, 2, 0.9)
    best = max(
        float(_gain(mdp, acts).max())
        for acts in itertools.product(*[np.flatnonzero(mdp.action_mask[s]) for s in range(4)])
    )
    res = relative_value_iteration(mdp, tol=1e-10)
    assert res.converged and res.gain is not None
    assert res.gain == pytest.approx(best, abs=1e-8)
    assert res.v[0] == 0.0
    # the returned policy achieves it
    assert _gain(mdp, tuple(res.policy.action_indices())) == pytest.approx(best, abs=1e-8)
    # h satisfies the optimality equation g + h = max_a (r + P h)
    tv = pl.planning.bellman_optimality_backup(mdp, res.v, gamma=1.0)
    assert tv - res.v == pytest.approx(np.full(4, res.gain), abs=1e-7)


def test_relative_value_iteration_robot_and_periodic_chain() -> None:
    robot = pl.problems.recycling_robot()
    assert relative_value_iteration(robot).gain == pytest.approx(4 / 1.3)
    flip = pl.FiniteMDP.from_dynamics(
        {"a": {"go": [(1.0, "b", 1.0)]}, "b": {"go": [(1.0, "a", 0.0)]}}, gamma=0.9
    )
    with pytest.warns(NotConvergedWarning, match="tau"):
        relative_value_iteration(flip, max_iter=50)
    assert relative_value_iteration(flip, tau=0.5).gain == pytest.approx(0.5)


def test_special_solver_errors() -> None:
    grid = pl.problems.mountain_gridworld()
    with pytest.raises(InvalidMDPError, match="continuing task"):
        relative_value_iteration(grid)
    with pytest.raises(InvalidArgumentError, match="horizon"):
        backward_induction(grid, 0)
    robot = pl.problems.recycling_robot()
    with pytest.raises(InvalidArgumentError, match="tau"):
        relative_value_iteration(robot, tau=0)
    with pytest.raises(InvalidArgumentError, match="reference"):
        relative_value_iteration(robot, reference=7)
    with pytest.raises(InvalidMDPError, match="continuing task"):
        pl.planning.linear_programming(robot, gamma=1.0)
