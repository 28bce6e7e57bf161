"""Learning curves: the bootstrap band, smoothing, result reading, several algorithms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from synthetic import FakeResult

from policylab.exceptions import InvalidArgumentError
from policylab.plot import (
    bootstrap_ci,
    learning_curves,
    learning_figure,
    moving_average,
    save_learning_figure,
)


def test_bootstrap_ci_matches_scipy_percentile_bootstrap():
    rng = np.random.default_rng(1)
    x = rng.normal(2.0, 1.0, size=(30, 3))
    lo, hi = bootstrap_ci(x, confidence=0.9, n_resamples=20_000, seed=0)
    ref = stats.bootstrap(
        (x,),
        np.mean,
        axis=0,
        confidence_level=0.9,
        n_resamples=20_000,
        method="percentile",
        random_state=np.random.default_rng(0),
    ).confidence_interval
    np.testing.assert_allclose(lo, ref.low, atol=0.02)
    np.testing.assert_allclose(hi, ref.high, atol=0.02)
    assert np.all(lo < x.mean(axis=0)) and np.all(x.mean(axis=0) < hi)


def test_bootstrap_ci_is_reproducible_and_degenerate_on_equal_runs():
    x = np.tile(np.arange(5.0), (4, 1))
    lo, hi = bootstrap_ci(x, seed=3)
    np.testing.assert_allclose(lo, np.arange(5.0))
    np.testing.assert_allclose(hi, np.arange(5.0))
    y = np.random.default_rng(0).normal(size=(6, 4))
    a, b = bootstrap_ci(y, seed=7), bootstrap_ci(y, seed=7)
    np.testing.assert_array_equal(a[0], b[0])
    with pytest.raises(InvalidArgumentError, match="confidence"):
        bootstrap_ci(y, confidence=1.5)
    with pytest.raises(InvalidArgumentError, match="n_runs, n_points"):
        bootstrap_ci(np.zeros(3))


def test_moving_average_is_the_trailing_mean():
    x = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    np.testing.assert_allclose(moving_average(x, 2), [1.0, 1.5, 2.5, 3.5, 4.5])
    np.testing.assert_allclose(moving_average(x, 1), x)


def test_learning_curves_read_results_and_mappings():
    r = FakeResult(0)
    c = learning_curves(r)
    np.testing.assert_array_equal(c.episode_returns, r.episode_returns)
    np.testing.assert_array_equal(c.error, r.error_rms)
    np.testing.assert_array_equal(c.checkpoints, r.checkpoints)
    m = learning_curves({"episode_returns": [1, 2, 3], "error": {"max": [0.5, 0.1]}})
    np.testing.assert_array_equal(m.error, [0.5, 0.1])
    np.testing.assert_array_equal(m.checkpoints, [1.5, 3.0])  # spread over the episodes
    with pytest.raises(InvalidArgumentError, match="neither"):
        learning_curves(object())
    with pytest.raises(InvalidArgumentError, match="4 checkpoints"):
        learning_curves({"errors": [1.0, 2.0], "checkpoints": [1, 2, 3, 4]})


def test_several_algorithms_share_one_figure_with_bands(tmp_path):
    runs = {
        "MC": [FakeResult(s) for s in range(4)],
        "Q-learning": [FakeResult(10 + s, episodes=150) for s in range(4)],
    }
    fig = learning_figure(runs, title="two learners")
    err_ax, ret_ax = fig.axes
    assert [t.get_text() for t in err_ax.get_legend().get_texts()] == [
        "MC (n=4)",
        "Q-learning (n=4)",
    ]
    assert len(ret_ax.collections) == 2  # one confidence band per algorithm
    mean = np.mean([r.error_rms for r in runs["MC"]], axis=0)
    np.testing.assert_allclose(err_ax.lines[0].get_ydata(), mean)
    path = save_learning_figure(runs, tmp_path / "curves.svg")
    text = path.read_text()
    assert path.suffix == ".svg" and "<svg" in text


def test_one_result_draws_without_a_band(tmp_path):
    fig = learning_figure(FakeResult(1))
    assert all(len(ax.collections) == 0 for ax in fig.axes)
    only_returns = {"episode_returns": np.arange(10.0)}
    assert len(learning_figure(only_returns).axes) == 1
