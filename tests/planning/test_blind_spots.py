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
