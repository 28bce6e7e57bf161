"""FrozenLake-v1 read from Gymnasium and solved: the known optimum of the start state."""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.planning import linear_programming


def test_frozenlake_optimum_of_the_start_state() -> None:
    mdp = pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=1.0)
    # Undiscounted, v_*(start) is the best probability of reaching the goal: 14/17.
    pi = pl.policy_iteration(mdp)
    assert pi.v[0] == pytest.approx(14 / 17, abs=1e-12)
    assert pl.value_iteration(mdp, tol=1e-12).v[0] == pytest.approx(14 / 17, abs=1e-9)
    assert linear_programming(mdp).v[0] == pytest.approx(14 / 17, abs=1e-7)
    # gamma = 0.99: the value usually quoted for the discounted task.
    res = pl.value_iteration(mdp, gamma=0.99, tol=1e-10)
    assert res.v[0] == pytest.approx(0.5420, abs=1e-4)
    assert np.allclose(pl.policy_iteration(mdp, gamma=0.99).v, res.v, atol=1e-9)
