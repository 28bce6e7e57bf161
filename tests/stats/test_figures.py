"""The statistics figures of policylab.plot draw what policylab.stats computes."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.plot import (
    aggregate_intervals_figure,
    align_curves,
    performance_profile_figure,
    run_curves_figure,
)
from policylab.stats import performance_profile, performance_profile_ci, summarize

A = np.array([[0.2, 0.9], [0.4, 0.7], [0.3, 0.8], [0.5, 0.6]])
B = A - 0.3


def test_aggregate_intervals_draw_each_interval_and_estimate() -> None:
    summaries = {"a": summarize(A, reps=200), "b": summarize(B, reps=200)}
    fig = aggregate_intervals_figure(summaries, confidence=0.95)
    axes = fig.axes
    assert [ax.get_title().split("\n")[0] for ax in axes] == [
        "IQM",
        "Mean",
        "Median",
        "Optimality gap",
    ]
    assert [t.get_text() for t in axes[0].get_yticklabels()] == ["a", "b"]
    for ax, stat in zip(axes, ["iqm", "mean", "median", "optimality_gap"], strict=True):
        bars = ax.patches
        for bar, lab in zip(bars, ["a", "b"], strict=True):
            e = summaries[lab][stat]
            assert bar.get_x() == pytest.approx(e["low"])
            assert bar.get_x() + bar.get_width() == pytest.approx(e["high"])
        ticks = [line.get_xdata()[0] for line in ax.lines]
        assert ticks == pytest.approx(
            [summaries["a"][stat]["value"], summaries["b"][stat]["value"]]
        )
    assert "lower is better" in axes[3].get_title()


def test_performance_profile_figure_draws_the_profile_and_its_band() -> None:
    taus = np.linspace(0, 1, 21)
    fig = performance_profile_figure({"a": A, "b": B}, taus, reps=300, seed=5)
    ax = fig.axes[0]
    for line, x in zip(ax.lines, [A, B], strict=True):
        np.testing.assert_array_equal(line.get_xdata(), taus)
        np.testing.assert_array_equal(line.get_ydata(), performance_profile(x, taus))
    low, high = performance_profile_ci(A, taus, reps=300, seed=5)  # seed + 0 for the first
    band = ax.collections[0].get_paths()[0].vertices
    assert band[:, 1].min() == pytest.approx(low.min())
    assert band[:, 1].max() == pytest.approx(high.max())
    # default thresholds span all scores
    fig = performance_profile_figure({"a": A}, reps=50)
    xs = fig.axes[0].lines[0].get_xdata()
    assert xs[0] < A.min() and xs[-1] > A.max()


def test_align_curves_stacks_equal_grids_and_interpolates_others() -> None:
    x, ys = align_curves([([0, 1, 2], [0.0, 1.0, 2.0]), ([0, 1, 2], [2.0, 3.0, 4.0])])
    np.testing.assert_array_equal(x, [0, 1, 2])
    np.testing.assert_array_equal(ys, [[0, 1, 2], [2, 3, 4]])
    # logged at other points: the grid of the shortest run within the shared range
    x, ys = align_curves([([0, 10, 20], [0.0, 1.0, 2.0]), ([0, 5, 10, 15, 20, 25], [0] * 6)])
    np.testing.assert_array_equal(x, [0, 10, 20])
    np.testing.assert_array_equal(ys, [[0, 1, 2], [0, 0, 0]])
    x, ys = align_curves([([0, 10], [0.0, 10.0]), ([5, 10, 15], [1.0, 1.0, 1.0])])
    np.testing.assert_array_equal(x, [10])  # only 10 lies in both ranges, [5, 10]
    # non-finite points are dropped for all runs
    x, ys = align_curves([([0, 1, 2], [0.0, np.nan, 2.0]), ([0, 1, 2], [1.0, 1.0, 1.0])])
    np.testing.assert_array_equal(x, [0, 2])
    with pytest.raises(InvalidArgumentError, match="share no range"):
        align_curves([([0, 1], [0, 0]), ([5, 6, 7], [0, 0, 0])])
    with pytest.raises(InvalidArgumentError, match="curve 1 has 2 x values and 1 y values"):
        align_curves([([0], [0]), ([0, 1], [0])])


def test_run_curves_figure_draws_the_mean_per_task() -> None:
    runs = [([0, 1, 2], [0.0, 1.0, 2.0]), ([0, 1, 2], [2.0, 3.0, 6.0])]
    fig = run_curves_figure({"lake": {"a": runs}, "cliff": {"a": runs[:1]}}, x_label="episode")
    lake, cliff = fig.axes[:2]
    assert (lake.get_title(), cliff.get_title()) == ("lake", "cliff")
    np.testing.assert_array_equal(lake.lines[0].get_ydata(), [1.0, 2.0, 4.0])
    assert lake.get_xlabel() == "episode"
    assert len(lake.collections) == 1 and len(cliff.collections) == 0  # one run: no band


def test_figures_refuse_empty_or_incomplete_input() -> None:
    with pytest.raises(InvalidArgumentError, match="non-empty mapping"):
        aggregate_intervals_figure({})
    with pytest.raises(InvalidArgumentError, match="has no 'iqm' with value, low and high"):
        aggregate_intervals_figure({"a": {"mean": {"value": 1.0}}})
    with pytest.raises(InvalidArgumentError, match="non-empty mapping"):
        performance_profile_figure({})
    with pytest.raises(NonFiniteError, match=r"scores\['a'\]\[0, 0\]"):
        performance_profile_figure({"a": [[np.nan]]})
    with pytest.raises(InvalidArgumentError, match="at least one run's curve"):
        run_curves_figure({"lake": {"a": []}})
