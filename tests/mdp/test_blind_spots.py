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
