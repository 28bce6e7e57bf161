"""The planning classics reproduce their published numbers (book precision)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.planning import backward_induction, linear_programming, relative_value_iteration
from policylab.problems import (
    forest_management,
    gamblers_bold_policy,
    gamblers_problem,
    gridworld_4x4,
    gridworld_5x5,
    inventory_management,
    jacks_car_rental,
    jacks_no_move_policy,
    random_mdp,
)

# Sutton & Barto, Figure 3.2 (right): the equiprobable random policy, gamma 0.9.
FIG_3_2 = [
    [3.3, 8.8, 4.4, 5.3, 1.5],
    [1.5, 3.0, 2.3, 1.9, 0.5],
    [0.1, 0.7, 0.7, 0.4, -0.4],
    [-1.0, -0.4, -0.4, -0.6, -1.2],
    [-1.9, -1.3, -1.2, -1.4, -2.0],
]
# Figure 3.5 (middle): v_*.
FIG_3_5 = [
    [22.0, 24.4, 22.0, 19.4, 17.5],
    [19.8, 22.0, 19.8, 17.8, 16.0],
    [17.8, 19.8, 17.8, 16.0, 14.4],
    [16.0, 17.8, 16.0, 14.4, 13.0],
    [14.4, 16.0, 14.4, 13.0, 11.7],
]
# Figure 4.1 (k = infinity): the random policy on the 4 x 4 gridworld.
FIG_4_1 = [[0, -14, -20, -22], [-14, -18, -20, -20], [-20, -20, -18, -14], [-22, -20, -14, 0]]


def test_example_3_5_random_policy() -> None:
    mdp = gridworld_5x5()
    assert mdp.grid is not None
    v = pl.evaluate_policy(mdp, pl.Policy.uniform(mdp))
    assert np.round(mdp.grid.to_array(v), 1).tolist() == FIG_3_2


def test_example_3_8_optimum_and_optimal_actions() -> None:
    mdp = gridworld_5x5()
    assert mdp.grid is not None
    for res in (
        pl.value_iteration(mdp, tol=1e-6),
        pl.policy_iteration(mdp),
        linear_programming(mdp),
    ):
        assert np.round(mdp.grid.to_array(res.v), 1).tolist() == FIG_3_5
    res = pl.policy_iteration(mdp)
    best = res.optimal_actions(mdp, tol=1e-6)
    assert set(best[(0, 1)]) == {"up", "down", "left", "right"}  # A: every action jumps
    assert best[(4, 4)] == ["up", "left"]  # Figure 3.5 (right), bottom-right corner
    assert best[(0, 0)] == ["right"]


def test_figure_4_1_and_its_greedy_policy() -> None:
    mdp = gridworld_4x4()
    assert mdp.grid is not None
    for method in ("exact", "iterative"):
        v = pl.evaluate_policy(mdp, pl.Policy.uniform(mdp), method=method)
        assert np.round(mdp.grid.to_array(v)).tolist() == FIG_4_1
    v_star = pl.policy_iteration(mdp).v
    assert mdp.grid.to_array(v_star)[0].tolist() == [0, -1, -2, -3]


def test_gamblers_problem() -> None:
    mdp = gamblers_problem()
    assert mdp.meta["xlabel"] == "Capital" and len(mdp.meta["x"]) == 101
    res = pl.value_iteration(mdp, tol=1e-12)
    assert res.v[50] == pytest.approx(0.4)
    assert res.v[25] == pytest.approx(0.16)
    assert res.v[75] == pytest.approx(0.64)
    # bold play is optimal for p_h < 1/2, and its value is v_*
    assert np.allclose(pl.evaluate_policy(mdp, gamblers_bold_policy(mdp)), res.v, atol=1e-10)
    assert np.allclose(pl.policy_iteration(mdp).v, res.v, atol=1e-10)
    assert res.optimal_actions(mdp, tol=1e-9)[50] == [50]
    # p_h > 1/2: timid play (stake 1) is optimal, v_*(s) = (1 - (q/p)^s) / (1 - (q/p)^100)
    fair = gamblers_problem(p_h=0.55)
    r = (0.45 / 0.55) ** np.arange(101)
    assert np.allclose(pl.policy_iteration(fair).v[1:100], ((1 - r) / (1 - r[100]))[1:100])
    with pytest.raises(InvalidArgumentError, match="p_h"):
        gamblers_problem(p_h=1.0)


def test_jacks_car_rental_policy_iteration() -> None:
    mdp = jacks_car_rental()
    assert mdp.n_states == 441 and mdp.actions == tuple(range(-5, 6))
    assert mdp.grid is not None and mdp.grid.moves == () and mdp.grid.shape == (21, 21)
    assert mdp.meta["axis_labels"] == ("cars at first location", "cars at second location")
    res = pl.policy_iteration(mdp, policy=jacks_no_move_policy(mdp))
    # Figure 4.2: pi_0 -> pi_4, four improvements, then the policy is stable.
    assert int((res.history > 0).sum()) == 4 and res.history[-1] == 0
    acts = np.array([mdp.actions[a] for a in res.policy.action_indices()]).reshape(21, 21)
    assert acts[20, 0] == 5 and acts[0, 20] == -4 and acts[10, 10] == 0  # pi_4's corners
    assert res.v.min() == pytest.approx(421, abs=1)  # bottom of Figure 4.2's v_4 (420)
    # the reward of each outcome is E[R | s, a, s']: r(s, a) is exact
    assert mdp.expected_reward[0, mdp.action_index(0)] == pytest.approx(0.0)


def test_forest_matches_pymdptoolbox_docs() -> None:
    mdp = forest_management()
    res = pl.policy_iteration(mdp)
    assert res.v == pytest.approx([26.244, 29.484, 33.484], abs=1e-9)
    assert res.policy.to_dict() == {"0": {"wait": 1.0}, "1": {"wait": 1.0}, "2": {"wait": 1.0}}
    fh = backward_induction(mdp, 3)
    assert fh.stage_values is not None and fh.stage_actions is not None
    assert fh.stage_values[:3].T.round(4).tolist() == [
        [2.6973, 0.81, 0.0],
        [5.9373, 3.24, 1.0],
        [9.9373, 7.24, 4.0],
    ]
    assert fh.stage_actions.T.tolist() == [[0, 0, 0], [0, 0, 1], [0, 0, 0]]
    assert relative_value_iteration(mdp).gain == pytest.approx(3.24)


def test_inventory_management() -> None:
    mdp = inventory_management()
    assert mdp.available_actions(10) == [0]
    assert mdp.available_actions(0) == list(range(11))
    res = pl.policy_iteration(mdp)
    assert np.allclose(pl.value_iteration(mdp, tol=1e-9).v, res.v, atol=1e-8)
    # expected reward by hand for s = 0, a = 0: nothing to sell, all demand lost
    assert mdp.expected_reward[0, 0] == pytest.approx(-2.0 * 3.0)
    # with a fixed ordering cost the optimum is an (s, S) policy: order up to S when low
    order = [mdp.actions[a] for a in res.policy.action_indices()]
    low = [s for s in range(11) if order[s] > 0]
    assert low == list(range(len(low))) and len({s + order[s] for s in low}) == 1


def test_random_mdp_is_sparse_and_seeded() -> None:
    a, b = random_mdp(50, 3, 5, seed=1), random_mdp(50, 3, 5, seed=1)
    assert np.array_equal(a.next_states, b.next_states) and np.array_equal(a.probs, b.probs)
    assert not np.array_equal(a.probs, random_mdp(50, 3, 5, seed=2).probs)
    assert a.n_outcomes == 50 * 3 * 5
    nxt = a.next_states.reshape(150, 5)
    assert np.all(np.diff(nxt, axis=1) > 0)  # distinct and sorted
    assert a.transition_matrix.has_canonical_format
    with pytest.raises(InvalidArgumentError, match="n_successors"):
        random_mdp(5, 2, 6)
    with pytest.raises(InvalidArgumentError, match="n_states"):
        random_mdp(0)


@pytest.mark.parametrize(
    "name",
    [
        "gridworld-5x5",
        "gridworld-4x4",
        "gamblers-problem",
        "jacks-car-rental",
        "inventory-management",
        "forest-management",
        "random-mdp",
    ],
)
def test_registered_and_gymnasium_ready(name: str) -> None:
    spec = pl.problems.problem(name)
    env = gym.make(spec.gym_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()
