"""Stratified bootstrap confidence intervals of aggregate scores.

The bootstrap of Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge of
the Statistical Precipice" (NeurIPS): a resampled score matrix draws, for each task
separately, N runs with replacement from that task's N runs (stratified: runs of one
task never stand in for another's); the statistic of each of B resampled matrices
gives its bootstrap distribution, and the percentile interval is that distribution's
((1 - c) / 2, (1 + c) / 2) quantiles for confidence c.

The resampling is vectorised: a chunk of resampled matrices is one fancy-indexing of
an index array of shape (chunk, N, M), and policylab's own statistics are batched
kernels applied to the whole chunk at once. Chunks are sized by the matrix, so memory
stays bounded at any ``reps``, and the same seed always gives the same interval.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.stats.aggregates import (
    FloatArray,
    _iqm,
    _mean,
    _median,
    _optimality_gap,
    _performance_profile,
    _probability_of_improvement,
    check_pair,
    check_scores,
    check_taus,
    iqm,
    mean,
    median,
    optimality_gap,
)
from policylab.validation import Seed, as_generator, check_count, check_number, fmt_number

__all__ = [
    "DEFAULT_REPS",
    "SUMMARY_STATISTICS",
    "bootstrap_ci",
    "bootstrap_distribution",
    "performance_profile_ci",
    "probability_of_improvement_ci",
    "summarize",
]

#: Bootstrap resamples used when none is given.
DEFAULT_REPS = 2000

#: The aggregates :func:`summarize` reports, in order.
SUMMARY_STATISTICS = ("iqm", "mean", "median", "optimality_gap")

#: Resampled scores held in memory at once (float64 values plus int64 indices).
_CHUNK_ELEMENTS = 1 << 21

Kernel = Callable[[FloatArray], FloatArray]

_KERNELS: dict[Callable[..., float], Callable[..., FloatArray]] = {
    mean: _mean,
    median: _median,
    iqm: _iqm,
    optimality_gap: _optimality_gap,
}


def _kernel(statistic: Any) -> Kernel:
    """A batched version of ``statistic``: policylab's own kernel, or a loop over a callable.

    ``functools.partial(optimality_gap, threshold=0.5)`` gets the batched kernel too.
    """
    func, kwargs = statistic, {}
    if isinstance(statistic, functools.partial) and not statistic.args:
        func, kwargs = statistic.func, dict(statistic.keywords)
    try:
        known = _KERNELS.get(func)
    except TypeError:  # an unhashable callable
        known = None
    if known is not None:
        if func is optimality_gap and "threshold" in kwargs:
            kwargs["threshold"] = check_number(kwargs["threshold"], "threshold")
        return functools.partial(known, **kwargs) if kwargs else known
    if not callable(statistic):
        raise InvalidArgumentError(
            f"statistic must be a function of a (runs, tasks) score matrix, such as "
            f"policylab.stats.iqm; got {type(statistic).__name__} {statistic!r}"
        )
    name = getattr(statistic, "__name__", repr(statistic))

    def loop(batch: FloatArray) -> FloatArray:
        out = np.empty(batch.shape[0])
        for i, sample in enumerate(batch):
            value = statistic(sample)
            try:
                out[i] = float(value)
            except (TypeError, ValueError):
                raise InvalidArgumentError(
                    f"statistic {name} must return one number for a (runs, tasks) matrix; "
                    f"it returned {type(value).__name__} {value!r}"
                ) from None
        return out

    return loop


def _check_confidence(confidence: Any) -> float:
    return check_number(confidence, "confidence", low=0.0, high=1.0, low_open=True, high_open=True)


def _resample(x: FloatArray, count: int, rng: np.random.Generator) -> FloatArray:
    """``count`` stratified resamples of x: (count, N, M), column m drawn from column m."""
    n, m = x.shape
    rows = rng.integers(0, n, size=(count, n, m))
    return x[rows, np.arange(m)]


def _chunks(reps: int, matrix_size: int) -> list[int]:
    per = max(1, _CHUNK_ELEMENTS // max(1, matrix_size))
    return [min(per, reps - start) for start in range(0, reps, per)]


def bootstrap_distribution(
    scores: ArrayLike,
    statistics: Sequence[Callable[..., Any]] | Callable[..., Any],
    *,
    reps: int = DEFAULT_REPS,
    seed: Seed = None,
) -> FloatArray:
    """The statistics of ``reps`` stratified bootstrap resamples of a score matrix.

    Each resample draws, for every task m, N runs with replacement from task m's runs.
    All statistics are computed on the same resamples (as rliable does when its
    aggregate function returns several numbers), so their intervals are consistent.

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.
        statistics: One statistic or a sequence of them. policylab's ``mean``,
            ``median``, ``iqm`` and ``optimality_gap`` (also as a ``functools.partial``
            with keywords) are computed batched; any other function of a (runs, tasks)
            matrix returning a number is called once per resample.
        reps: Number of resamples B.
        seed: Seed or generator of the resampling.

    Returns:
        (reps,) for one statistic, (reps, K) for a sequence of K.

    Raises:
        InvalidArgumentError: Bad scores, reps, or a statistic that is not a function.
        NonFiniteError: If a score is NaN or infinite.
    """
    x = check_scores(scores)
    one = not isinstance(statistics, Sequence)
    stats_list: list[Callable[..., Any]] = (
        [statistics] if not isinstance(statistics, Sequence) else list(statistics)
    )
    if not stats_list:
        raise InvalidArgumentError("statistics is empty; give at least one statistic")
    kernels = [_kernel(s) for s in stats_list]
    reps = check_count(reps, "reps")
    rng = as_generator(seed)
    out = np.empty((reps, len(kernels)))
    start = 0
    for count in _chunks(reps, x.size):
        batch = _resample(x, count, rng)
        for k, kernel in enumerate(kernels):
            out[start : start + count, k] = kernel(batch)
        start += count
    return out[:, 0] if one else out


def _percentile_interval(dist: FloatArray, confidence: float) -> tuple[FloatArray, FloatArray]:
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.quantile(dist, [alpha, 1.0 - alpha], axis=0)
    return np.asarray(lo), np.asarray(hi)


def bootstrap_ci(
    scores: ArrayLike,
    statistic: Callable[..., Any],
    *,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: Seed = None,
) -> tuple[float, float]:
    """Stratified bootstrap percentile confidence interval of an aggregate score.

    With T_b the statistic of the b-th of B stratified resamples (see
    :func:`bootstrap_distribution`), the interval is
    [q_{(1-c)/2}(T_1..T_B), q_{(1+c)/2}(T_1..T_B)], q the empirical quantile (linear
    interpolation) and c the confidence: the percentile interval of Agarwal et al. (2021),
    "Deep Reinforcement Learning at the Edge of the Statistical Precipice", and rliable's
    ``get_interval_estimates``.

    Example::

        low, high = pl.stats.bootstrap_ci(scores, pl.stats.iqm, reps=2000, seed=0)

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.
        statistic: A function of a (runs, tasks) matrix returning a number, such as
            :func:`~policylab.stats.iqm` (policylab's own are computed batched).
        reps: Number of resamples B.
        confidence: Coverage c of the interval, in (0, 1).
        seed: Seed or generator; the same seed gives the same interval.

    Returns:
        (low, high) as Python floats.

    Raises:
        InvalidArgumentError: Bad scores, reps, confidence or statistic.
        NonFiniteError: If a score is NaN or infinite.
    """
    if isinstance(statistic, Sequence) or not callable(statistic):
        raise InvalidArgumentError(
            f"statistic must be one function of a (runs, tasks) score matrix, such as "
            f"policylab.stats.iqm; got {type(statistic).__name__}"
        )
    confidence = _check_confidence(confidence)
    dist = bootstrap_distribution(scores, statistic, reps=reps, seed=seed)
    _check_finite_distribution(dist, getattr(statistic, "__name__", "the statistic"))
    lo, hi = _percentile_interval(dist, confidence)
    return float(lo), float(hi)


def _check_finite_distribution(dist: FloatArray, name: str) -> None:
    bad = ~np.isfinite(dist)
    if bad.any():
        first = fmt_number(float(dist[bad][0]))
        raise NonFiniteError(
            f"{name} gave {first} on {int(bad.sum())} of {bad.size} bootstrap resamples; a "
            "confidence interval needs a finite statistic"
        )


def summarize(
    scores: ArrayLike,
    *,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: Seed = 0,
    threshold: float = 1.0,
) -> dict[str, dict[str, float]]:
    """IQM, mean, median and optimality gap of a score matrix, each with its interval.

    The four aggregates of Agarwal et al. (2021) with stratified bootstrap percentile
    intervals computed on the same resamples (see :func:`bootstrap_ci`).

    Args:
        scores: (runs, tasks) matrix, or a 1-D array of the runs of one task.
        reps: Number of bootstrap resamples.
        confidence: Coverage of the intervals, in (0, 1).
        seed: Seed or generator of the resampling (fixed by default: the same scores give
            the same summary).
        threshold: Target gamma of the optimality gap.

    Returns:
        ``{"iqm": {"value", "low", "high"}, "mean": ..., "median": ...,
        "optimality_gap": ...}``, plain floats (JSON-ready).

    Raises:
        InvalidArgumentError: Bad scores, reps, confidence or threshold.
        NonFiniteError: If a score is NaN or infinite.
    """
    x = check_scores(scores)
    confidence = _check_confidence(confidence)
    gap = functools.partial(optimality_gap, threshold=check_number(threshold, "threshold"))
    funcs: list[Callable[..., float]] = [iqm, mean, median, gap]
    dist = bootstrap_distribution(x, funcs, reps=reps, seed=seed)
    lo, hi = _percentile_interval(dist, confidence)
    return {
        name: {"value": float(f(x)), "low": float(lo[k]), "high": float(hi[k])}
        for k, (name, f) in enumerate(zip(SUMMARY_STATISTICS, funcs, strict=True))
    }


def performance_profile_ci(
    scores: ArrayLike,
    taus: ArrayLike,
    *,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: Seed = None,
) -> tuple[FloatArray, FloatArray]:
    """Pointwise stratified bootstrap interval of a performance profile.

    For each tau, the percentile interval of F_b(tau) over B stratified resamples,
    F(tau) = (1 / M) sum_m (1 / N) sum_n 1[x_{n,m} > tau] (see
    :func:`~policylab.stats.performance_profile`), as rliable's
    ``create_performance_profile`` draws its bands.

    Returns:
        (low, high), each of shape (len(taus),).

    Raises:
        InvalidArgumentError: Bad scores, taus, reps or confidence.
        NonFiniteError: If a score or threshold is NaN or infinite.
    """
    x = check_scores(scores)
    t = check_taus(taus)
    confidence = _check_confidence(confidence)
    reps = check_count(reps, "reps")
    rng = as_generator(seed)
    out = np.empty((reps, t.size))
    start = 0
    for count in _chunks(reps, x.size * t.size):
        out[start : start + count] = _performance_profile(_resample(x, count, rng), t)
        start += count
    return _percentile_interval(out, confidence)


def probability_of_improvement_ci(
    x: ArrayLike,
    y: ArrayLike,
    *,
    reps: int = DEFAULT_REPS,
    confidence: float = 0.95,
    seed: Seed = None,
) -> tuple[float, float]:
    """Stratified bootstrap interval of the probability that X improves on Y.

    The runs of X and of Y are resampled independently, each within its tasks, and
    P(X > Y) (see :func:`~policylab.stats.probability_of_improvement`) is computed on
    every pair of resamples; the interval is the percentile interval of those values
    (rliable's ``get_interval_estimates`` on a pair of algorithms).

    Returns:
        (low, high) as Python floats.

    Raises:
        InvalidArgumentError: Bad scores (or different numbers of tasks), reps or
            confidence.
        NonFiniteError: If a score is NaN or infinite.
    """
    a, b = check_pair(x, y)
    confidence = _check_confidence(confidence)
    reps = check_count(reps, "reps")
    rng = as_generator(seed)
    out = np.empty(reps)
    start = 0
    for count in _chunks(reps, a.shape[0] * b.shape[0] * a.shape[1]):
        ra = _resample(a, count, rng)
        rb = _resample(b, count, rng)
        out[start : start + count] = _probability_of_improvement(ra, rb)
        start += count
    lo, hi = _percentile_interval(out, confidence)
    return float(lo), float(hi)
