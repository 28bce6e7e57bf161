"""The stratified bootstrap: exact small cases, stratification, seeds, coverage."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.stats import bootstrap as bootstrap_module
from policylab.stats import (
    bootstrap_ci,
    bootstrap_distribution,
    iqm,
    mean,
    median,
    optimality_gap,
    performance_profile,
    performance_profile_ci,
    probability_of_improvement,
    probability_of_improvement_ci,
    summarize,
)


def test_two_runs_resample_to_the_exact_bootstrap_distribution() -> None:
    # Runs {0, 1} of one task: a resample's mean is 0, 1/2 or 1 with probability 1/4, 1/2, 1/4.
    dist = bootstrap_distribution([0.0, 1.0], mean, reps=40_000, seed=3)
    values, counts = np.unique(dist, return_counts=True)
    np.testing.assert_array_equal(values, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(counts / dist.size, [0.25, 0.5, 0.25], atol=0.01)


def test_bootstrap_variance_of_the_mean_is_the_plug_in_variance_over_n() -> None:
    # For the mean of one task, Var*(mean of a resample) = (1/n) * (1/n) sum (x_i - xbar)^2.
    x = np.array([0.0, 1.0, 3.0, 7.0, 2.0])
    dist = bootstrap_distribution(x, mean, reps=50_000, seed=0)
    exact = np.var(x) / x.size
    assert dist.var() == pytest.approx(exact, rel=0.03)
    assert dist.mean() == pytest.approx(x.mean(), abs=0.02)


def test_resampling_never_mixes_tasks() -> None:
    scores = np.array([[0.0, 100.0, -5.0], [1.0, 101.0, -6.0], [0.0, 100.0, -5.0]])
    seen = []

    def record(sample: np.ndarray) -> float:
        seen.append(sample.copy())
        return 0.0

    bootstrap_distribution(scores, record, reps=300, seed=1)
    for sample in seen:
        assert sample.shape == (3, 3)
        assert set(sample[:, 0]) <= {0.0, 1.0}
        assert set(sample[:, 1]) <= {100.0, 101.0}
        assert set(sample[:, 2]) <= {-5.0, -6.0}
    # the batched kernels see the same stratified resamples: the mean stays within the
    # range a per-task resample allows, (0 + 100 - 6) / 3 .. (1 + 101 - 5) / 3
    dist = bootstrap_distribution(scores, mean, reps=3000, seed=1)
    assert dist.min() >= 94 / 3 - 1e-12 and dist.max() <= 97 / 3 + 1e-12
    means = np.array([s.mean() for s in seen])
    np.testing.assert_allclose(bootstrap_distribution(scores, mean, reps=300, seed=1), means)


def test_batched_kernels_agree_with_the_functions_on_every_resample() -> None:
    rng = np.random.default_rng(0)
    scores = rng.normal(size=(7, 3))
    gap = functools.partial(optimality_gap, threshold=0.2)
    fast = bootstrap_distribution(scores, [iqm, mean, median, gap], reps=200, seed=4)
    slow = bootstrap_distribution(
        scores,
        [lambda s: iqm(s), lambda s: mean(s), lambda s: median(s), lambda s: gap(s)],
        reps=200,
        seed=4,
    )
    np.testing.assert_allclose(fast, slow, atol=1e-12)


def test_chunking_gives_the_same_interval(monkeypatch: pytest.MonkeyPatch) -> None:
    scores = np.random.default_rng(2).normal(size=(10, 4))
    whole = bootstrap_distribution(scores, iqm, reps=500, seed=9)
    monkeypatch.setattr(bootstrap_module, "_CHUNK_ELEMENTS", 40 * 7)  # chunks of 7 resamples
    np.testing.assert_array_equal(bootstrap_distribution(scores, iqm, reps=500, seed=9), whole)


def test_same_seed_same_interval_and_the_interval_holds_the_estimate() -> None:
    scores = np.random.default_rng(3).uniform(size=(10, 5))
    a = bootstrap_ci(scores, iqm, reps=1000, seed=11)
    assert a == bootstrap_ci(scores, iqm, reps=1000, seed=11)
    assert a != bootstrap_ci(scores, iqm, reps=1000, seed=12)
    assert a[0] < iqm(scores) < a[1]
    assert type(a[0]) is float and type(a[1]) is float
    gen = np.random.default_rng(11)
    assert bootstrap_ci(scores, iqm, reps=1000, seed=gen) == a


def test_percentile_interval_is_the_quantiles_of_the_distribution() -> None:
    scores = np.random.default_rng(4).normal(size=(8, 2))
    dist = bootstrap_distribution(scores, median, reps=999, seed=5)
    low, high = bootstrap_ci(scores, median, reps=999, confidence=0.9, seed=5)
    assert low == np.quantile(dist, 0.05) and high == np.quantile(dist, 0.95)
    lo50, hi50 = bootstrap_ci(scores, median, reps=999, confidence=0.5, seed=5)
    assert low < lo50 < hi50 < high


def test_summarize_is_json_ready_and_matches_bootstrap_ci() -> None:
    scores = np.random.default_rng(6).uniform(size=(6, 3))
    summary = summarize(scores, reps=500, seed=2)
    assert list(summary) == ["iqm", "mean", "median", "optimality_gap"]
    assert json.loads(json.dumps(summary)) == summary
    assert summary["iqm"]["value"] == iqm(scores)
    assert summary["optimality_gap"]["value"] == optimality_gap(scores)
    for entry in summary.values():
        assert set(entry) == {"value", "low", "high"}
        assert entry["low"] <= entry["value"] <= entry["high"]
    # every statistic is computed on the same resamples as a lone bootstrap_ci would use
    assert (summary["iqm"]["low"], summary["iqm"]["high"]) == bootstrap_ci(
        scores, iqm, reps=500, seed=2
    )
    assert summarize(scores, reps=500, seed=2) == summary  # seed 0 by default: reproducible
    assert summarize(scores, reps=500) == summarize(scores, reps=500)


def test_constant_scores_give_a_point_interval() -> None:
    summary = summarize(np.full((5, 2), 0.3), reps=100)
    for name, entry in summary.items():
        expected = 0.7 if name == "optimality_gap" else 0.3
        assert entry["low"] == pytest.approx(expected) == entry["high"]


def test_performance_profile_band_holds_the_profile() -> None:
    scores = np.random.default_rng(7).uniform(size=(20, 3))
    taus = np.linspace(0, 1, 11)
    low, high = performance_profile_ci(scores, taus, reps=1000, seed=0)
    prof = performance_profile(scores, taus)
    assert low.shape == high.shape == (11,)
    assert np.all(low <= prof + 1e-12) and np.all(prof <= high + 1e-12)
    assert low[0] == high[0] == 1.0 and low[-1] == high[-1] == 0.0  # uniform on (0, 1)
    assert np.all(high[1:-1] > low[1:-1])


def test_probability_of_improvement_interval() -> None:
    rng = np.random.default_rng(8)
    x = rng.normal(1.0, 1.0, size=(15, 2))
    y = rng.normal(0.0, 1.0, size=(12, 2))
    low, high = probability_of_improvement_ci(x, y, reps=2000, seed=0)
    assert low < probability_of_improvement(x, y) < high
    assert low > 0.5  # one standard deviation apart: clearly better
    assert (low, high) == probability_of_improvement_ci(x, y, reps=2000, seed=0)


def test_coverage_of_the_95_percent_interval_on_simulated_experiments() -> None:
    """The 95% intervals of the mean and the IQM cover the true value in 95% +- 2% of runs.

    Each simulated experiment has 40 runs on each of 2 tasks, N(0, 1) and N(3, 1): their
    mixture is symmetric about 1.5, so the mean and the IQM (the 25% trimmed mean of the
    mixture) are both 1.5. With 2000 experiments, the standard error of the coverage is
    0.49%. Resampling across tasks would widen the intervals (between-task spread) and
    cover far too often; an interval that ignores the spread would cover far too little.
    """
    rng = np.random.default_rng(2021)
    n_experiments, truth = 2000, 1.5
    covered = {"mean": 0, "iqm": 0}
    for _ in range(n_experiments):
        scores = rng.normal(size=(40, 2)) + np.array([0.0, 3.0])
        summary = summarize(scores, reps=500, seed=rng)
        for name in covered:
            covered[name] += summary[name]["low"] <= truth <= summary[name]["high"]
    for name, count in covered.items():
        assert abs(count / n_experiments - 0.95) <= 0.02, (name, count / n_experiments)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"reps": 0}, "reps must be a positive integer; got 0"),
        ({"reps": 2.5}, "reps must be an integer"),
        ({"confidence": 1.0}, "confidence must be in (0, 1); got 1.0"),
        ({"confidence": 0}, "confidence must be in (0, 1); got 0"),
        ({"seed": -1}, "seed must be a non-negative integer"),
    ],
)
def test_bad_bootstrap_arguments(kwargs: dict[str, object], words: str) -> None:
    with pytest.raises(InvalidArgumentError) as info:
        bootstrap_ci(np.ones((3, 2)), iqm, **kwargs)  # type: ignore[arg-type]
    assert words in str(info.value)


def test_bad_statistics() -> None:
    with pytest.raises(InvalidArgumentError, match="statistic must be one function"):
        bootstrap_ci(np.ones((3, 2)), "iqm")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match="must return one number"):
        bootstrap_ci(np.ones((3, 2)), lambda s: s.mean(axis=0))
    with pytest.raises(NonFiniteError, match="bootstrap resamples"):
        bootstrap_ci(np.ones((3, 2)), lambda s: float("nan"))
    with pytest.raises(NonFiniteError, match=r"scores\[2, 0\]"):
        summarize([[1.0], [2.0], [float("-inf")]])
    with pytest.raises(InvalidArgumentError, match="threshold must be a number; got 'x'"):
        bootstrap_ci(np.ones((3, 2)), functools.partial(optimality_gap, threshold="x"))
    assert pl.stats.bootstrap_ci is bootstrap_ci
