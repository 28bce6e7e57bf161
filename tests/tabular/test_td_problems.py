"""The chapter 6 problems against their exact answers (linear solves, value iteration)."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.planning import evaluate_policy, value_iteration


def test_random_walk_true_values_are_one_sixth_to_five_sixths():
    mdp = pl.problems.random_walk()
    assert mdp.states == ("left", "A", "B", "C", "D", "E", "right")
    assert mdp.states[int(np.argmax(mdp.initial))] == "C"
    v = evaluate_policy(mdp, pl.Policy.uniform(mdp))
    np.testing.assert_allclose(v, [0, 1 / 6, 2 / 6, 3 / 6, 4 / 6, 5 / 6, 0], atol=1e-12)
    np.testing.assert_allclose(pl.problems.random_walk_true_values(), v, atol=1e-12)
    assert mdp.meta["x"][1:6] == [1.0, 2.0, 3.0, 4.0, 5.0]


def test_nineteen_state_walk_with_left_reward_minus_one():
    mdp = pl.problems.random_walk(19, left_reward=-1.0)
    v = evaluate_policy(mdp, pl.Policy.uniform(mdp))
    np.testing.assert_allclose(v, pl.problems.random_walk_true_values(19, -1.0), atol=1e-10)
    np.testing.assert_allclose(v[1:20], np.arange(-18, 20, 2) / 20, atol=1e-10)


def test_random_walk_rejects_even_sizes():
    with pytest.raises(InvalidArgumentError, match="odd"):
        pl.problems.random_walk(4)


def test_cliff_walking_equals_gymnasium_model():
    ours = pl.problems.cliff_walking()
    theirs = pl.FiniteMDP.from_gymnasium("CliffWalking-v1")
    for field in (
        "indptr",
        "next_states",
        "probs",
        "rewards",
        "terminal",
        "action_mask",
        "initial",
    ):
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field), err_msg=field)
    assert ours.actions == ("up", "right", "down", "left")


def test_cliff_walking_optimal_path_is_thirteen_steps():
    res = value_iteration(pl.problems.cliff_walking(), tol=1e-10)
    start = pl.problems.cliff_walking().state_index((3, 0))
    assert res.v[start] == pytest.approx(-13.0)


@pytest.mark.parametrize(("king", "steps"), [(False, 15), (True, 7)])
def test_windy_gridworld_shortest_episode(king, steps):
    mdp = pl.problems.windy_gridworld(king_moves=king)
    res = value_iteration(mdp, tol=1e-10)
    assert res.v[mdp.state_index((3, 0))] == pytest.approx(-steps)


def test_windy_gridworld_wind_pushes_up():
    mdp = pl.problems.windy_gridworld()
    # From (3, 6) (wind 2) moving right lands two rows up in column 7.
    assert mdp.outcomes((3, 6), "right") == [(1.0, (1, 7), -1.0)]
    # Wind never pushes off the grid.
    assert mdp.outcomes((0, 7), "up") == [(1.0, (0, 7), -1.0)]


def test_maximization_bias_mdp():
    mdp = pl.problems.maximization_bias()
    res = value_iteration(mdp, tol=1e-12)
    a = mdp.state_index("A")
    assert res.q[a, mdp.action_index("right")] == pytest.approx(0.0)
    assert res.q[a, mdp.action_index("left")] == pytest.approx(-0.1)
    outs = mdp.outcomes("B", "b3")
    p = np.array([o[0] for o in outs])
    r = np.array([o[2] for o in outs])
    assert p.sum() == pytest.approx(1.0)
    assert p @ r == pytest.approx(-0.1)
    assert p @ (r + 0.1) ** 2 == pytest.approx(1.0)  # variance 1
    assert p @ (r + 0.1) ** 4 == pytest.approx(3.0)  # kurtosis of the normal
    assert mdp.available_actions("A") == ["right", "left"]
    assert len(mdp.available_actions("B")) == 10


@pytest.mark.parametrize(
    "gym_id", ["RandomWalk", "CliffWalking", "WindyGridworld", "MaximizationBias"]
)
def test_registered_gymnasium_ids_pass_check_env(gym_id):
    env = gym.make(f"policylab/{gym_id}-v0")
    check_env(env.unwrapped, skip_render_check=True)
