"""evaluate_policy, action_values, greedy_policy, compare_policies on the notes' problems."""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import (
    InvalidArgumentError,
    InvalidMDPError,
    InvalidPolicyError,
    NotConvergedWarning,
    ShapeError,
)


@pytest.fixture
def robot() -> pl.FiniteMDP:
    return pl.problems.recycling_robot()


def robot_oracle(alpha: float = 0.7, beta: float = 0.2, g: float = 0.9) -> np.ndarray:
    """v_pi of pi(high) = search, pi(low) = recharge, by hand (2 x 2 solve)."""
    # v_h = 4 + g (alpha v_h + (1 - alpha) v_l);  v_l = 0 + g v_h
    A = np.array([[1 - g * alpha, -g * (1 - alpha)], [-g, 1.0]])
    return np.linalg.solve(A, [4.0, 0.0])


def test_robot_deterministic_policy_value(robot: pl.FiniteMDP) -> None:
    pi = pl.problems.recycling_robot_deterministic_policy(robot)
    expected = robot_oracle()
    for kw in ({}, {"method": "iterative"}, {"method": "iterative", "in_place": True}):
        assert np.allclose(pl.evaluate_policy(robot, pi, **kw), expected, atol=1e-9)  # type: ignore[call-overload]


def test_robot_stochastic_policy_and_comparison(robot: pl.FiniteMDP) -> None:
    det = pl.problems.recycling_robot_deterministic_policy(robot)
    sto = pl.problems.recycling_robot_stochastic_policy(robot)
    # By hand: v_l = .5 (0 + g v_h) + .4 (1 + g v_l) + .1 (.2 (4 + g v_l) + .8 (-3 + g v_h))
    g = 0.9
    A = np.array([[1 - g * 0.7, -g * 0.3], [-(0.5 * g + 0.08 * g), 1 - 0.4 * g - 0.02 * g]])
    b = np.array([4.0, 0.4 + 0.1 * (0.8 - 2.4)])
    assert np.allclose(pl.evaluate_policy(robot, sto), np.linalg.solve(A, b))
    assert pl.compare_policies(robot, det, sto) == "better"
    assert pl.compare_policies(robot, sto, det) == "worse"
    assert pl.compare_policies(robot, det, det) == "equal"


def test_incomparable_policies() -> None:
    mdp = pl.FiniteMDP.from_dynamics(
        {
            "x": {"a": [(1.0, "end", 1.0)], "b": [(1.0, "end", 0.0)]},
            "y": {"a": [(1.0, "end", 0.0)], "b": [(1.0, "end", 1.0)]},
        },
        terminal=["end"],
    )
    p1 = pl.Policy.deterministic(mdp, {"x": "a", "y": "a"})
    p2 = pl.Policy.deterministic(mdp, {"x": "b", "y": "b"})
    assert pl.compare_policies(mdp, p1, p2) == "incomparable"


def test_mountain_bad_policy_and_optimum() -> None:
    mdp = pl.problems.mountain_gridworld()
    bad = pl.problems.mountain_gridworld_bad_policy(mdp)
    v = pl.evaluate_policy(mdp, bad)
    assert v[mdp.state_index((2, 0))] == pytest.approx(-6.0)
    assert v[mdp.state_index((2, 1))] == pytest.approx(-5.0)
    res = pl.policy_iteration(mdp)
    assert res.v[mdp.state_index((2, 0))] == pytest.approx(4.0)
    assert pl.compare_policies(mdp, res.policy, bad) == "better"
    q = pl.action_values(mdp, res.v)
    assert q[mdp.state_index((2, 1)), mdp.action_index("right")] == pytest.approx(5.0)
    assert np.allclose(pl.evaluate_policy(mdp, pl.greedy_policy(mdp, q)), res.v)
    assert pl.optimal_actions(mdp, q)[np.arange(9), res.policy.action_indices()][:8].all()


def test_action_values_masks_unavailable_actions(robot: pl.FiniteMDP) -> None:
    q = pl.action_values(robot, [1.0, 2.0])
    assert q[robot.state_index("high"), robot.action_index("recharge")] == -np.inf
    assert q[robot.state_index("low"), robot.action_index("wait")] == pytest.approx(1 + 0.9 * 2)


def test_greedy_ties_and_all_optimal_actions() -> None:
    mdp = pl.FiniteMDP.from_dynamics(
        {
            "s": {
                "a": [(1.0, "end", 1.0)],
                "b": [(1.0, "end", 1.0 + 1e-12)],
                "c": [(1.0, "end", 0.0)],
            }
        },
        terminal=["end"],
    )
    q = pl.action_values(mdp, np.zeros(2))
    assert pl.greedy_policy(mdp, q).to_dict() == {"s": {"a": 1.0}}
    assert pl.greedy_policy(mdp, q, ties="uniform").to_dict() == {"s": {"a": 0.5, "b": 0.5}}
    assert pl.optimal_actions(mdp, q)[0].tolist() == [True, True, False]
    assert pl.greedy_policy(mdp, q, tol=1e-15).to_dict() == {"s": {"b": 1.0}}
    res = pl.value_iteration(mdp)
    assert res.optimal_actions(mdp) == {"s": ["a", "b"]}
    with pytest.raises(InvalidArgumentError, match="ties"):
        pl.greedy_policy(mdp, q, ties="random")


def test_gamma_one_continuing_task_names_states(robot: pl.FiniteMDP) -> None:
    pi = pl.problems.recycling_robot_deterministic_policy(robot)
    with pytest.raises(InvalidPolicyError, match=r"continuing task.*'high'"):
        pl.evaluate_policy(robot, pi, gamma=1.0)
    with pytest.raises(InvalidMDPError, match="relative_value_iteration"):
        pl.value_iteration(robot, gamma=1.0)


def test_gamma_one_improper_policy_names_states() -> None:
    mdp = pl.problems.mountain_gridworld()
    acts = {s: "right" for s in mdp.states if not mdp.terminal[mdp.state_index(s)]}
    acts[(0, 2)] = "up"  # stuck in the top-right corner forever
    acts[(0, 1)] = "right"
    pi = pl.Policy.deterministic(mdp, acts)
    with pytest.raises(InvalidPolicyError, match=r"no terminal state is reached.*\(0, 2\)") as e:
        pl.evaluate_policy(mdp, pi)
    assert "(2, 0)" not in str(e.value)  # (2, 0) -> (2, 1) -> (2, 2) goal is fine
    for method in ("exact", "iterative"):
        with pytest.raises(InvalidPolicyError):
            pl.evaluate_policy(mdp, pi, method=method)
    # with gamma < 1 the same policy has a value
    assert np.isfinite(pl.evaluate_policy(mdp, pi, gamma=0.9)).all()


def test_bad_arguments(robot: pl.FiniteMDP) -> None:
    pi = pl.Policy.uniform(robot)
    with pytest.raises(InvalidArgumentError, match="method"):
        pl.evaluate_policy(robot, pi, method="magic")
    with pytest.raises(InvalidArgumentError, match="gamma"):
        pl.evaluate_policy(robot, pi, gamma=1.5)
    with pytest.raises(ShapeError, match=r"expected \(S,\) = \(2,\)"):
        pl.action_values(robot, [1.0, 2.0, 3.0])
    with pytest.raises(ShapeError, match=r"\(S, A\) = \(2, 3\)"):
        pl.greedy_policy(robot, np.zeros((3, 3)))
    with pytest.raises(InvalidArgumentError, match="finite"):
        pl.action_values(robot, [np.nan, 1.0])
    with pytest.raises(InvalidArgumentError, match="tol"):
        pl.value_iteration(robot, tol=-1)
    with pytest.raises(InvalidArgumentError, match="max_iter"):
        pl.value_iteration(robot, max_iter=0)
    with pytest.raises(InvalidArgumentError, match="evaluation"):
        pl.policy_iteration(robot, evaluation="guess")
    other = pl.problems.mountain_gridworld()
    with pytest.raises(InvalidPolicyError, match="another MDP"):
        pl.evaluate_policy(robot, pl.Policy.uniform(other))
    with pytest.raises(InvalidPolicyError):
        pl.evaluate_policy(robot, np.ones((2, 3)))


def test_value_iteration_warns_at_max_iter(robot: pl.FiniteMDP) -> None:
    with pytest.warns(NotConvergedWarning, match="max_iter"):
        res = pl.value_iteration(robot, max_iter=2)
    assert not res.converged
    assert res.iterations == 2
    assert res.error_bound is not None
    v_star = pl.policy_iteration(robot).v
    assert np.max(np.abs(res.v - v_star)) <= res.error_bound


def test_value_iteration_bound_is_honest_and_tight_enough(robot: pl.FiniteMDP) -> None:
    v_star = pl.policy_iteration(robot).v
    for tol in (1e-2, 1e-5, 1e-9):
        for gs in (False, True):
            res = pl.value_iteration(robot, tol=tol, gauss_seidel=gs)
            assert res.error_bound is not None and res.error_bound <= tol
            assert np.max(np.abs(res.v - v_star)) <= res.error_bound + 1e-12
            assert len(res.history) == res.iterations
