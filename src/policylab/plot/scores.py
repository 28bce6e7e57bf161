"""Figures of statistics over runs: aggregate intervals, performance profiles, curve bands.

The three figures of Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge of
the Statistical Precipice", for configurations (or algorithms) scored over runs and
tasks, computed with :mod:`policylab.stats`:

- :func:`aggregate_intervals_figure`: IQM, mean, median and optimality gap of each
  configuration as a point with its confidence interval, one panel per statistic;
- :func:`performance_profile_figure`: the fraction of runs scoring above tau, with a
  bootstrap band, one curve per configuration;
- :func:`run_curves_figure`: learning curves as the mean over runs with a bootstrap
  band, one panel per task.

Each configuration keeps its colour (``C0``, ``C1``, ... in the order given) in all three.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.plot._common import new_figure
from policylab.plot.learning import draw_mean_with_band

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "STATISTIC_NAMES",
    "aggregate_intervals_figure",
    "align_curves",
    "performance_profile_figure",
    "run_curves_figure",
]

#: How each statistic of :func:`policylab.stats.summarize` is titled in a figure.
STATISTIC_NAMES = {
    "iqm": "IQM",
    "mean": "Mean",
    "median": "Median",
    "optimality_gap": "Optimality gap",
}


def _nonempty(mapping: Mapping[str, Any], what: str) -> None:
    if not isinstance(mapping, Mapping) or not mapping:
        raise InvalidArgumentError(f"{what} needs a non-empty mapping {{label: ...}}")


def aggregate_intervals_figure(
    summaries: Mapping[str, Mapping[str, Mapping[str, float]]],
    *,
    statistics: Sequence[str] = ("iqm", "mean", "median", "optimality_gap"),
    score_label: str = "score",
    confidence: float | None = None,
    title: str | None = None,
) -> Figure:
    """Each configuration's aggregates as points with their confidence intervals.

    One panel per statistic, one row per configuration (top: first given): a bar from
    the interval's low to high end and a tick at the point estimate, as in Agarwal et
    al. (2021), Figure 1. The optimality gap is better when lower; the others when higher.

    Args:
        summaries: ``{label: policylab.stats.summarize(scores)}``: per statistic a
            mapping with ``value``, ``low`` and ``high``.
        statistics: The statistics to draw, in order (keys of each summary).
        score_label: What the scores are (x-axis label).
        confidence: The intervals' coverage, for the caption (None: not said).
        title: Figure title.

    Raises:
        InvalidArgumentError: If ``summaries`` is empty or lacks a statistic.
    """
    _nonempty(summaries, "an aggregate-interval figure")
    labels = list(summaries)
    for lab in labels:
        for s in statistics:
            entry = summaries[lab].get(s)
            if not isinstance(entry, Mapping) or not {"value", "low", "high"} <= set(entry):
                raise InvalidArgumentError(
                    f"summary of {lab!r} has no {s!r} with value, low and high; expected "
                    "what policylab.stats.summarize returns"
                )
    n = len(labels)
    fig = new_figure(max(7.0, 2.6 * len(statistics)), 1.2 + 0.42 * n)
    axes = fig.subplots(1, len(statistics), sharey=True, squeeze=False)[0]
    ys = np.arange(n)[::-1]
    for ax, stat in zip(axes, statistics, strict=True):
        for k, (lab, y) in enumerate(zip(labels, ys, strict=True)):
            e = summaries[lab][stat]
            color = f"C{k % 10}"
            ax.barh(y, e["high"] - e["low"], left=e["low"], height=0.6, color=color, alpha=0.45)
            ax.plot([e["value"]] * 2, [y - 0.3, y + 0.3], color=color, lw=2.2)
        better = "lower is better" if stat == "optimality_gap" else "higher is better"
        ax.set_title(f"{STATISTIC_NAMES.get(stat, stat)}\n({better})", fontsize=10)
        ax.set_xlabel(score_label, fontsize=9)
        ax.grid(axis="x", alpha=0.3)
        ax.margins(x=0.08)
    axes[0].set_yticks(ys, labels, fontsize=9)
    band = f"{confidence:.0%} " if confidence is not None else ""
    fig.suptitle(
        (title or "Aggregate scores") + f"\n(point estimate and {band}stratified bootstrap CI)",
        fontsize=11,
    )
    return fig


def performance_profile_figure(
    scores: Mapping[str, ArrayLike],
    taus: ArrayLike | None = None,
    *,
    reps: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
    score_label: str = "score",
    title: str | None = None,
) -> Figure:
    """Performance profiles: the fraction of runs scoring above tau, with bootstrap bands.

    F(tau) = (1 / M) sum_m (1 / N) sum_n 1[x_{n,m} > tau] for each configuration's
    (runs, tasks) scores (:func:`policylab.stats.performance_profile`), with its
    pointwise stratified bootstrap band (:func:`policylab.stats.performance_profile_ci`),
    as in Agarwal et al. (2021), Figure 5. A profile above another everywhere is
    better for every threshold (stochastic dominance).

    Args:
        scores: ``{label: (runs, tasks) scores}``.
        taus: Thresholds (default: 101 points spanning all scores).
        reps: Bootstrap resamples of the bands.
        confidence: Coverage of the bands.
        seed: Seed of the resampling.
        score_label: What the scores are (x-axis label).
        title: Figure title.

    Raises:
        InvalidArgumentError: If ``scores`` is empty, or a matrix or ``taus`` is invalid.
    """
    from policylab.stats import performance_profile, performance_profile_ci
    from policylab.stats.aggregates import check_scores

    _nonempty(scores, "a performance-profile figure")
    mats = {lab: check_scores(x, f"scores[{lab!r}]") for lab, x in scores.items()}
    if taus is None:
        lo = min(float(x.min()) for x in mats.values())
        hi = max(float(x.max()) for x in mats.values())
        pad = 0.02 * (hi - lo) if hi > lo else 0.5
        t = np.linspace(lo - pad, hi + pad, 101)
    else:
        t = np.asarray(taus, dtype=np.float64)
    fig = new_figure(6.5, 4.2)
    ax = fig.add_subplot()
    for k, (lab, x) in enumerate(mats.items()):
        color = f"C{k % 10}"
        prof = performance_profile(x, t)
        ax.plot(
            t, prof, color=color, lw=1.8, drawstyle="steps-post", label=f"{lab} (n={x.shape[0]})"
        )
        if x.shape[0] > 1:
            low, high = performance_profile_ci(
                x, t, reps=reps, confidence=confidence, seed=seed + k
            )
            ax.fill_between(t, low, high, color=color, alpha=0.2, lw=0, step="post")
    ax.set_xlabel(f"{score_label} threshold τ")
    ax.set_ylabel("fraction of runs with score > τ")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, frameon=False)
    ax.set_title(
        (title or "Performance profiles") + f"\n({confidence:.0%} stratified bootstrap bands)",
        fontsize=11,
    )
    return fig


def align_curves(
    curves: Sequence[tuple[ArrayLike, ArrayLike]],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Curves of several runs on one x grid: ``(x, ys)`` with ys of shape (runs, points).

    Runs logged at the same points are stacked as they are. Otherwise the grid is the x
    values of the run with the fewest points that lie within every run's range, and each
    run is interpolated linearly onto it. Points where a run's value is not finite are
    dropped for all.

    Raises:
        InvalidArgumentError: No curves, a curve whose x and y differ in length, or no
            x range that all runs share.
    """
    if not curves:
        raise InvalidArgumentError("no curves to align")
    pairs = []
    for i, (x, y) in enumerate(curves):
        xs, ys = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        if xs.ndim != 1 or xs.shape != ys.shape or xs.size == 0:
            raise InvalidArgumentError(
                f"curve {i} has {xs.size} x values and {ys.size} y values; expected the same "
                "positive number"
            )
        order = np.argsort(xs, kind="stable")
        pairs.append((xs[order], ys[order]))
    first = pairs[0][0]
    if all(p[0].shape == first.shape and np.array_equal(p[0], first) for p in pairs):
        grid, stack = first, np.stack([p[1] for p in pairs])
    else:
        lo = max(float(p[0][0]) for p in pairs)
        hi = min(float(p[0][-1]) for p in pairs)
        shortest = min(pairs, key=lambda p: p[0].size)[0]
        grid = shortest[(shortest >= lo) & (shortest <= hi)]
        if grid.size == 0:
            raise InvalidArgumentError(
                "the runs' curves share no range of x; they cannot be averaged"
            )
        stack = np.stack([np.interp(grid, px, py) for px, py in pairs])
    keep = np.all(np.isfinite(stack), axis=0)
    return grid[keep], stack[:, keep]


def run_curves_figure(
    curves: Mapping[str, Mapping[str, Sequence[tuple[ArrayLike, ArrayLike]]]],
    *,
    x_label: str = "step",
    y_label: str = "score",
    confidence: float = 0.95,
    title: str | None = None,
) -> Figure:
    """Learning curves over runs: mean with a bootstrap band, one panel per task.

    Args:
        curves: ``{task: {label: [(x, y) per run]}}``; runs of one configuration are
            aligned by :func:`align_curves`.
        x_label: What x counts ("episode", "step").
        y_label: What y measures.
        confidence: Coverage of the band (a percentile bootstrap of the mean over runs).
        title: Figure title.

    Raises:
        InvalidArgumentError: If there are no curves at all.
    """
    _nonempty(curves, "a learning-curve figure")
    tasks = [t for t, by_label in curves.items() if any(by_label.values())]
    if not tasks:
        raise InvalidArgumentError("a learning-curve figure needs at least one run's curve")
    labels = list(dict.fromkeys(lab for t in curves for lab in curves[t]))
    fig = new_figure(max(6.5, 5.0 * len(tasks)), 4.2)
    axes = fig.subplots(1, len(tasks), squeeze=False)[0]
    for ax, task in zip(axes, tasks, strict=True):
        for lab, runs in curves[task].items():
            if not runs:
                continue
            k = labels.index(lab)
            x, ys = align_curves(runs)
            draw_mean_with_band(
                ax,
                x,
                ys,
                label=f"{lab} (n={ys.shape[0]})",
                color=f"C{k % 10}",
                confidence=confidence,
                seed=k,
            )
        ax.set_title(task, fontsize=10)
        ax.set_xlabel(x_label)
        ax.set_ylabel(y_label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, frameon=False)
    fig.suptitle(
        (title or "Learning curves") + f"\n(mean over runs with {confidence:.0%} bootstrap band)",
        fontsize=11,
    )
    return fig
