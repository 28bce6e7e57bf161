"""Policy: constructors, views, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidPolicyError


@pytest.fixture
def robot():
    return pl.problems.recycling_robot()


def test_deterministic_and_stochastic(robot):
    det = pl.Policy.deterministic(robot, {"low": "recharge", "high": "search"})
    np.testing.assert_array_equal(det.probs, [[1, 0, 0], [0, 0, 1]])
    assert det.is_deterministic and det("low") == "recharge"
    sto = pl.problems.recycling_robot_stochastic_policy(robot)
    np.testing.assert_allclose(sto.probs[1], [0.1, 0.4, 0.5])
    assert sto.prob("wait", "low") == pytest.approx(0.4)
    assert not sto.is_deterministic
    assert json.loads(json.dumps(sto.to_dict())) == {
        "high": {"search": 1.0},
        "low": {"search": 0.1, "wait": 0.4, "recharge": 0.5},
    }


def test_uniform_respects_available_actions(robot):
    u = pl.Policy.uniform(robot)
    np.testing.assert_allclose(u.probs, [[0.5, 0.5, 0.0], [1 / 3, 1 / 3, 1 / 3]])


def test_from_array_round_trip_and_terminal_rows_ignored():
    mdp = pl.problems.mountain_gridworld()
    probs = np.full((mdp.n_states, 4), 0.25)
    pi = pl.Policy.from_array(mdp, probs)
    goal = mdp.state_index((2, 2))
    assert pi.probs[goal].sum() == 0.0
    np.testing.assert_allclose(pl.Policy.from_array(mdp, pi.probs).probs, pi.probs)
    assert pi == pl.Policy.uniform(mdp)


def test_sampling_is_seeded(robot):
    sto = pl.problems.recycling_robot_stochastic_policy(robot)
    a = [sto.sample(1, np.random.default_rng(3)) for _ in range(5)]
    assert a == [sto.sample(1, np.random.default_rng(3)) for _ in range(5)]
    rng = np.random.default_rng(0)
    draws = np.bincount([sto.sample(1, rng) for _ in range(20000)], minlength=3) / 20000
    np.testing.assert_allclose(draws, [0.1, 0.4, 0.5], atol=0.015)


def test_policy_row_not_summing_to_one(robot):
    with pytest.raises(InvalidPolicyError, match=r"pi\(\. \| 'low'\) sums to 0\.9"):
        pl.Policy.stochastic(
            robot, {"high": {"search": 1.0}, "low": {"recharge": 0.5, "wait": 0.4}}
        )


def test_policy_on_unavailable_action(robot):
    with pytest.raises(
        InvalidPolicyError, match="'recharge' in state 'high', where it is not available"
    ):
        pl.Policy.deterministic(robot, {"high": "recharge", "low": "wait"})


def test_policy_unknown_state_label(robot):
    with pytest.raises(InvalidPolicyError, match="unknown state 'medium'"):
        pl.Policy.deterministic(robot, {"high": "search", "low": "wait", "medium": "wait"})


def test_policy_unknown_action_label(robot):
    with pytest.raises(InvalidPolicyError, match="state 'low' names unknown action 'dance'"):
        pl.Policy.deterministic(robot, {"high": "search", "low": "dance"})


def test_policy_missing_state(robot):
    with pytest.raises(
        InvalidPolicyError, match=r"no action for non-terminal state\(s\) \['low'\]"
    ):
        pl.Policy.deterministic(robot, {"high": "search"})


def test_policy_array_bad_shape_and_values(robot):
    with pytest.raises(InvalidPolicyError, match=r"shape \(2, 2\); expected \(S, A\) = \(2, 3\)"):
        pl.Policy.from_array(robot, np.ones((2, 2)) / 2)
    with pytest.raises(InvalidPolicyError, match="finite and >= 0"):
        pl.Policy.from_array(robot, [[1.5, -0.5, 0.0], [0, 0, 1]])


def test_deterministic_policy_with_a_list_of_actions_is_a_policy_error(robot):
    with pytest.raises(InvalidPolicyError, match=r"state 'high' is given \['search'\]"):
        pl.Policy.deterministic(robot, {"high": ["search"], "low": "recharge"})


def test_policy_arrays_of_strings_are_policy_errors(robot):
    with pytest.raises(InvalidPolicyError, match="array of numbers"):
        pl.Policy.from_array(robot, [["a", "b", "c"], ["d", "e", "f"]])
    with pytest.raises(InvalidPolicyError, match="one action index"):
        pl.Policy.from_actions(robot, ["search", "recharge"])


def test_policy_messages_show_numbers_plainly(robot):
    probs = np.array([[0.5, 0.5, 0.0], [0.3, 0.3, 0.3]])
    with pytest.raises(InvalidPolicyError) as err:
        pl.Policy.from_array(robot, probs)
    assert "sums to 0.9;" in str(err.value) and "np.float64" not in str(err.value)
