import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError, UnknownLabelError
from policylab.tabular import GroundTruth, StateIndex, checkpoint_episodes
from policylab.tabular.kernels import rand_uniform, rng_states, seed_states


def test_checkpoints_log_spaced_and_end_at_episodes():
    c = checkpoint_episodes(1000, 10)
    assert c[0] == 1 and c[-1] == 1000 and np.all(np.diff(c) > 0) and len(c) <= 10
    assert list(checkpoint_episodes(3, 50)) == [1, 2, 3]
    with pytest.raises(InvalidArgumentError):
        checkpoint_episodes(10, 0)


def test_state_index_kinds():
    d = StateIndex.discrete(3)
    assert d(np.int64(2)) == 2 and d.labels == (0, 1, 2)
    with pytest.raises(InvalidArgumentError):
        d(3)
    g = StateIndex.growing()
    assert g((4, np.int64(1), 0)) == 0 and g((5, 1, 0)) == 1 and g((4, 1, 0)) == 0
    assert g.labels == ((4, 1, 0), (5, 1, 0))
    f = StateIndex.of_labels([(4, 1, False), (4, 1, True)])
    assert f((4, 1, 1)) == 1  # Gymnasium's int flag finds the bool label
    with pytest.raises(UnknownLabelError):
        f((9, 9, 0))


def test_rng_states_reproducible_and_uniform():
    a, b = rng_states(5, 2), rng_states(5, 2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[0], a[1])
    u = np.array([rand_uniform(a[0]) for _ in range(20_000)])
    assert u.min() >= 0 and u.max() < 1 and abs(u.mean() - 0.5) < 0.01


def test_seed_states_are_each_seeds_own_rng_states():
    seeds = [0, 1, 5, 2**63 - 2, 123456789]
    expected = np.stack([rng_states(np.random.default_rng(s), 1)[0] for s in seeds])
    got = seed_states(seeds)
    assert got.dtype == np.uint64 and got.shape == (5, 4)
    np.testing.assert_array_equal(got, expected)
    assert seed_states([]).shape == (0, 4)


def test_ground_truth_errors_hand_computed():
    mdp = pl.problems.slippery_gridworld()
    truth = GroundTruth.control(mdp)
    e_max, e_rms, share = truth.errors(truth.q, truth.v)
    assert e_max == 0 and e_rms == 0 and share == 1.0
    q = truth.q + np.where(mdp.action_mask, 1.0, 0.0)
    e_max, e_rms, share = truth.errors(q, None)
    assert e_max == pytest.approx(1.0) and e_rms == pytest.approx(1.0) and share == 1.0
    assert np.isnan(GroundTruth.control(mdp, on="v").errors(None, truth.v)[2])


def test_ground_truth_is_solved_once_per_mdp_and_settings():
    """Many runs of one study share one exact solve; other settings solve again."""
    from policylab.planning import value_iteration

    mdp = pl.problems.cliff_walking()
    a = GroundTruth.control(mdp, on="q", gamma=0.9)
    assert GroundTruth.control(mdp, on="q", gamma=0.9) is a
    b = GroundTruth.control(mdp, on="q", gamma=0.5)
    assert b is not a
    np.testing.assert_allclose(b.v, value_iteration(mdp.with_gamma(0.5), tol=1e-10).v)
    pol = pl.Policy.uniform(mdp)
    p = GroundTruth.prediction(mdp, pol, on="v", gamma=0.9)
    assert GroundTruth.prediction(mdp, pl.Policy.uniform(mdp), on="v", gamma=0.9) is p
