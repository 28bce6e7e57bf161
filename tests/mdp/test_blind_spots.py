"""The FiniteMDP constructor itself (not only its builders) refuses a malformed model.

Terminal states are S+ minus S: value 0 and no outgoing dynamics. ``from_arrays`` and
``from_dynamics`` drop or refuse such rows before they reach the constructor, so these
tests build the outcome table by hand and call ``FiniteMDP(...)`` directly.
"""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidMDPError


def raw_mdp(terminal, action_mask, indptr, next_states, probs, rewards):
    return pl.FiniteMDP(
        states=("s", "end"),
        actions=("go",),
        gamma=0.9,
        terminal=np.asarray(terminal, dtype=bool),
        action_mask=np.asarray(action_mask, dtype=bool),
        indptr=np.asarray(indptr, dtype=np.int64),
        next_states=np.asarray(next_states, dtype=np.int64),
        probs=np.asarray(probs, dtype=np.float64),
        rewards=np.asarray(rewards, dtype=np.float64),
        initial=np.array([1.0, 0.0]),
    )


def test_constructor_accepts_a_well_formed_table():
    mdp = raw_mdp([False, True], [[True], [False]], [0, 1, 1], [1], [1.0], [2.0])
    assert mdp.outcomes("s", "go") == [(1.0, "end", 2.0)]
    np.testing.assert_allclose(pl.evaluate_policy(mdp, pl.Policy.uniform(mdp)), [2.0, 0.0])


@pytest.mark.parametrize("mask_of_end", [True, False])
def test_constructor_refuses_a_terminal_state_with_outgoing_dynamics(mask_of_end):
    # Row of (end, go) holds one outcome: end -> s. Whether or not A(end) lists "go",
    # a terminal state has no dynamics, so the model is malformed.
    with pytest.raises(InvalidMDPError, match=r"terminal state 'end' has outgoing dynamics"):
        raw_mdp(
            [False, True],
            [[True], [mask_of_end]],
            [0, 1, 2],
            [1, 0],
            [1.0, 1.0],
            [2.0, 0.0],
        )


def test_constructor_drops_terminal_rows_of_the_action_mask():
    # A(end) given as {go} but end is terminal (and has no outcomes): A(end) is empty.
    mdp = raw_mdp([False, True], [[True], [True]], [0, 1, 1], [1], [1.0], [2.0])
    assert mdp.action_mask.tolist() == [[True], [False]]
    assert mdp.available_actions("end") == []


def test_constructor_refuses_dynamics_of_an_unavailable_action():
    with pytest.raises(InvalidMDPError, match=r"action 'go' is not in A\('s'\) but has dynamics"):
        pl.FiniteMDP(
            states=("s", "t", "end"),
            actions=("go",),
            gamma=0.9,
            terminal=np.array([False, False, True]),
            action_mask=np.array([[False], [True], [False]]),
            indptr=np.array([0, 1, 2, 2]),
            next_states=np.array([2, 2]),
            probs=np.array([1.0, 1.0]),
            rewards=np.array([0.0, 0.0]),
            initial=np.array([0.0, 1.0, 0.0]),
        )


def test_constructor_refuses_a_start_distribution_on_a_terminal_state():
    with pytest.raises(InvalidMDPError, match=r"initial distribution puts mass on terminal state"):
        pl.FiniteMDP(
            states=("s", "end"),
            actions=("go",),
            gamma=0.9,
            terminal=np.array([False, True]),
            action_mask=np.array([[True], [False]]),
            indptr=np.array([0, 1, 1]),
            next_states=np.array([1]),
            probs=np.array([1.0]),
            rewards=np.array([0.0]),
            initial=np.array([0.5, 0.5]),
        )


@pytest.mark.parametrize("total", [1.0 - 1e-6, 1.0 + 1e-6, 0.99])
def test_probabilities_must_sum_to_one_to_within_the_stated_tolerance(total):
    """p(. | s, a) must sum to 1 to within 1e-8; an error of 1e-6 is refused."""
    with pytest.raises(InvalidMDPError, match=r"sums to .*each \(state, action\) must sum to 1"):
        pl.FiniteMDP.from_dynamics(
            {"s": {"go": [(total, "end", 0.0)]}}, gamma=0.9, terminal=("end",)
        )


@pytest.mark.parametrize("gamma", [1.5, -0.1])
def test_returns_refuse_a_discount_outside_0_1(gamma):
    from policylab.exceptions import InvalidArgumentError

    with pytest.raises(InvalidArgumentError, match="gamma must be in"):
        pl.discounted_return([1.0, 1.0], gamma)
    with pytest.raises(InvalidArgumentError, match="gamma must be in"):
        pl.returns_to_go([1.0, 1.0], gamma)
