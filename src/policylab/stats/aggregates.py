"""Aggregate scores over runs and tasks: mean, median, IQM, optimality gap, and more.

A score matrix holds one score per run (a seed) and task (a problem): shape
``(runs, tasks)``; a 1-D array is the runs of one task. Every aggregate here follows
Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge of the Statistical
Precipice" (NeurIPS), and its library rliable, so that numbers can be compared with
published ones.

Each aggregate is one public function that checks its input and returns a Python
float, and one batched kernel (``_iqm`` ...) that works on a stack of matrices of
shape ``(..., runs, tasks)`` at once: the bootstrap (:mod:`policylab.stats.bootstrap`)
calls the kernels on thousands of resampled matrices without a Python loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.validation import check_float_array, check_number, fmt_number

__all__ = [
    "check_pair",
    "check_scores",
    "check_taus",
    "iqm",
    "mean",
    "median",
    "optimality_gap",
    "performance_profile",
    "probability_of_improvement",
]

FloatArray = NDArray[np.float64]


def check_scores(scores: Any, name: str = "scores") -> FloatArray:
    """A score matrix as a ``(runs, tasks)`` float64 array (a 1-D array is one task).

    Args:
        scores: What the user gave: an array, nested lists, a list of floats.
        name: The argument's name in messages.

    Returns:
        A new 2-D float64 array with at least one run and one task.

    Raises:
        InvalidArgumentError: Not numbers, not 1-D or 2-D, or empty.
        NonFiniteError: A score is NaN or infinite (the position is named).
    """
    x = check_float_array(
        scores, name, expected="an array of scores, one row per run and one column per task"
    )
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise InvalidArgumentError(
            f"{name} must be a (runs, tasks) matrix or a 1-D array of runs of one task; "
            f"got an array of shape {x.shape}"
        )
    if x.shape[0] == 0 or x.shape[1] == 0:
        raise InvalidArgumentError(
            f"{name} is empty (shape {x.shape}); expected at least one run and one task"
        )
    bad = ~np.isfinite(x)
    if bad.any():
        r, t = (int(i) for i in np.argwhere(bad)[0])
        raise NonFiniteError(
            f"{name}[{r}, {t}] (run {r}, task {t}) is {fmt_number(float(x[r, t]))}; every "
            f"score must be a finite number ({int(bad.sum())} of {x.size} are not)"
        )
    return x


def check_taus(taus: Any, name: str = "taus") -> FloatArray:
    """Thresholds of a performance profile: a non-empty 1-D array of finite numbers."""
    t = np.atleast_1d(check_float_array(taus, name, expected="an array of score thresholds"))
    if t.ndim != 1 or t.size == 0:
        raise InvalidArgumentError(
            f"{name} must be a non-empty 1-D array of thresholds; got shape {t.shape}"
        )
    if not np.all(np.isfinite(t)):
        i = int(np.flatnonzero(~np.isfinite(t))[0])
        raise NonFiniteError(f"{name}[{i}] is {fmt_number(float(t[i]))}; thresholds must be finite")
    return t


# Batched kernels: x has shape (..., runs, tasks); the result drops the last two axes.


def _mean(x: FloatArray) -> FloatArray:
    return np.asarray(x.mean(axis=(-2, -1)))


def _median(x: FloatArray) -> FloatArray:
    return np.asarray(np.median(x.mean(axis=-2), axis=-1))


def _iqm(x: FloatArray) -> FloatArray:
    flat = x.reshape(*x.shape[:-2], -1)
    n = flat.shape[-1]
    lo = int(0.25 * n)  # scipy.stats.trim_mean's cut: int(proportion * n) on each side
    hi = n - lo
    middle = np.partition(flat, (lo, hi - 1), axis=-1)[..., lo:hi]
    return np.asarray(middle.mean(axis=-1))


def _optimality_gap(x: FloatArray, threshold: float = 1.0) -> FloatArray:
    return np.asarray(threshold - np.minimum(x, threshold).mean(axis=(-2, -1)))


def _performance_profile(x: FloatArray, taus: FloatArray) -> FloatArray:
    # (..., runs, tasks, T): the fraction over runs, then the mean over tasks.
    above = x[..., None] > taus
    return np.asarray(above.mean(axis=-3).mean(axis=-2))


def _probability_of_improvement(x: FloatArray, y: FloatArray) -> FloatArray:
    # (..., n, k, tasks): every pair of a run of x with a run of y on the same task.
    diff = x[..., :, None, :] - y[..., None, :, :]
    wins = (diff > 0).mean(axis=(-3, -2)) + 0.5 * (diff == 0).mean(axis=(-3, -2))
    return np.asarray(wins.mean(axis=-1))


def mean(scores: ArrayLike) -> float:
    """Mean score over all runs and tasks.

    mean = (1 / M) sum_m (1 / N) sum_n x_{n,m}, for N runs of M tasks: the mean over
    tasks of each task's mean score (rliable's ``aggregate_mean``).

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.

    Raises:
        InvalidArgumentError: If ``scores`` is empty or not 1-D/2-D numbers.
        NonFiniteError: If a score is NaN or infinite.
    """
    return float(_mean(check_scores(scores)))


def median(scores: ArrayLike) -> float:
    """Median over tasks of each task's mean score.

    median = median_m ( (1 / N) sum_n x_{n,m} ), as in Agarwal et al. (2021) and rliable's
    ``aggregate_median``: the runs of a task are averaged first, so with one task the
    median equals the mean. The paper recommends the IQM (:func:`iqm`) over it: the
    median ignores all but one or two tasks and has a wide interval with few runs.

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.

    Raises:
        InvalidArgumentError: If ``scores`` is empty or not 1-D/2-D numbers.
        NonFiniteError: If a score is NaN or infinite.
    """
    return float(_median(check_scores(scores)))


def iqm(scores: ArrayLike) -> float:
    """Interquartile mean: the mean of the middle 50% of all N x M scores.

    With the N M scores sorted, x_(1) <= ... <= x_(NM), and k = floor(NM / 4):
    IQM = (1 / (NM - 2k)) sum_{i=k+1}^{NM-k} x_(i), the 25% trimmed mean over the
    flattened matrix (``scipy.stats.trim_mean(scores, 0.25, axis=None)``, as rliable's
    ``aggregate_iqm``). Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge
    of the Statistical Precipice", recommend it: robust to outlier runs like the median,
    yet using half of all runs, so its interval is much narrower.

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.

    Raises:
        InvalidArgumentError: If ``scores`` is empty or not 1-D/2-D numbers.
        NonFiniteError: If a score is NaN or infinite.
    """
    return float(_iqm(check_scores(scores)))


def optimality_gap(scores: ArrayLike, threshold: float = 1.0) -> float:
    """How far scores fall short of a target, on average.

    gap = gamma - (1 / NM) sum_{n,m} min(x_{n,m}, gamma), with gamma = ``threshold``:
    scores above the target count as the target, so the gap is 0 when every run reaches
    it (Agarwal et al. 2021; rliable's ``aggregate_optimality_gap``). Lower is better.
    On normalised scores, gamma = 1 is the reference performance.

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.
        threshold: The target gamma.

    Raises:
        InvalidArgumentError: If ``scores`` is empty or not numbers, or ``threshold`` is
            not a finite number.
        NonFiniteError: If a score is NaN or infinite.
    """
    gamma = check_number(threshold, "threshold")
    return float(_optimality_gap(check_scores(scores), gamma))


def probability_of_improvement(x: ArrayLike, y: ArrayLike) -> float:
    """Probability that algorithm X beats algorithm Y on a random task.

    P(X > Y) = (1 / M) sum_m P(X_m > Y_m), with
    P(X_m > Y_m) = (1 / NK) sum_{i=1}^N sum_{j=1}^K S(x_{i,m}, y_{j,m}),
    S(a, b) = 1 if a > b, 1/2 if a = b, 0 otherwise: the Mann-Whitney U statistic of
    each task over N K, averaged over tasks (Agarwal et al. 2021; rliable's
    ``probability_of_improvement``). 0.5 means neither is better.

    Args:
        x: (N, tasks) scores of X.
        y: (K, tasks) scores of Y on the same tasks (K may differ from N).

    Raises:
        InvalidArgumentError: If either is empty or not numbers, or they have different
            numbers of tasks.
        NonFiniteError: If a score is NaN or infinite.
    """
    a, b = check_pair(x, y)
    return float(_probability_of_improvement(a, b))


def check_pair(x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Two score matrices of the same tasks (columns), each checked by :func:`check_scores`."""
    a, b = check_scores(x, "x"), check_scores(y, "y")
    if a.shape[1] != b.shape[1]:
        raise InvalidArgumentError(
            f"x and y must score the same tasks; x has {a.shape[1]} tasks (columns) and y "
            f"has {b.shape[1]}"
        )
    return a, b


def performance_profile(scores: ArrayLike, taus: ArrayLike) -> FloatArray:
    """Score distribution: the fraction of runs scoring above each threshold tau.

    F(tau) = (1 / M) sum_m (1 / N) sum_n 1[x_{n,m} > tau]: for each task, the fraction
    of runs with a score strictly above tau, averaged over tasks (Agarwal et al. 2021,
    run-score distributions; rliable's ``run_score_deviation`` convention). Unlike an
    aggregate it shows the whole distribution; one profile above another everywhere
    means stochastic dominance.

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.
        taus: 1-D array of thresholds.

    Returns:
        (len(taus),) fractions in [0, 1], non-increasing in tau.

    Raises:
        InvalidArgumentError: If ``scores`` or ``taus`` is empty or not numbers.
        NonFiniteError: If a score or threshold is NaN or infinite.
    """
    return _performance_profile(check_scores(scores), check_taus(taus))
