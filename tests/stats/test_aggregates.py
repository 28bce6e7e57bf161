"""Aggregates against hand-computed values and against scipy's definitions."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

import policylab as pl
from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.stats import (
    iqm,
    mean,
    median,
    optimality_gap,
    performance_profile,
    probability_of_improvement,
)

# 4 runs x 3 tasks; task means 1.5, 6.25, 0.5.
SCORES = np.array(
    [
        [0.0, 4.0, 0.5],
        [1.0, 5.0, 0.5],
        [2.0, 6.0, 0.5],
        [3.0, 10.0, 0.5],
    ]
)


def test_mean_is_the_mean_of_all_scores() -> None:
    assert mean(SCORES) == pytest.approx(33 / 12, abs=1e-15)


def test_median_is_the_median_of_the_task_means() -> None:
    assert median(SCORES) == pytest.approx(1.5, abs=1e-15)
    # one task: the median of one task mean is that mean, not the median of its runs
    assert median([0.0, 0.0, 9.0]) == pytest.approx(3.0)


def test_iqm_is_the_mean_of_the_middle_half_of_all_scores() -> None:
    # sorted: 0, .5, .5, .5, .5, 1, 2, 3, 4, 5, 6, 10; cut 3 each side: .5 .5 1 2 3 4
    assert iqm(SCORES) == pytest.approx(11 / 6, abs=1e-15)
    # 1-D: 8 runs, cut 2 each side
    assert iqm([10.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, -7.0]) == pytest.approx(2.5)
    # fewer than 4 scores: nothing is trimmed
    assert iqm([1.0, 2.0, 6.0]) == pytest.approx(3.0)


def test_iqm_matches_scipy_trim_mean() -> None:
    rng = np.random.default_rng(5)
    for shape in [(5, 3), (7, 1), (10, 4), (3, 3), (1, 1), (2, 9)]:
        x = rng.normal(size=shape)
        ref = scipy.stats.trim_mean(x, 0.25, axis=None)
        assert iqm(x) == pytest.approx(ref, abs=1e-12)


def test_optimality_gap_clips_at_the_threshold() -> None:
    # min(x, 1): 0+1+1+1, 1*4, .5*4 -> 9 / 12
    assert optimality_gap(SCORES) == pytest.approx(0.25, abs=1e-15)
    # min(x, 3): 0+1+2+3, 3*4, .5*4 -> 20 / 12
    assert optimality_gap(SCORES, threshold=3.0) == pytest.approx(3 - 20 / 12, abs=1e-15)
    assert optimality_gap([[2.0, 5.0]]) == 0.0


def test_performance_profile_hand_computed() -> None:
    prof = performance_profile(SCORES, [0.5, 2.0, 5.0, -1.0, 10.0])
    # tau = .5: 3/4, 4/4, 0 (0.5 is not above 0.5); tau = 2: 1/4, 1, 0; tau = 5: 0, 1/2, 0
    np.testing.assert_allclose(prof, [7 / 12, 5 / 12, 1 / 6, 1.0, 0.0], atol=1e-15)


def test_probability_of_improvement_hand_computed() -> None:
    x = [[1.0, 0.0], [3.0, 0.0]]
    y = [[0.0, 5.0], [1.0, 5.0], [2.0, 5.0]]
    # task 0: 1 > 0, 1 = 1 (1/2), 1 < 2, and 3 beats all three: 4.5 / 6; task 1: 0
    assert probability_of_improvement(x, y) == pytest.approx(0.375, abs=1e-15)
    assert probability_of_improvement(y, x) == pytest.approx(0.625, abs=1e-15)
    assert probability_of_improvement(x, x) == 0.5


def test_probability_of_improvement_is_mann_whitney_u_over_nk() -> None:
    rng = np.random.default_rng(1)
    x = rng.integers(0, 4, size=(6, 3)).astype(float)  # ties on purpose
    y = rng.integers(0, 4, size=(5, 3)).astype(float)
    ref = np.mean(
        [
            scipy.stats.mannwhitneyu(x[:, m], y[:, m], alternative="greater").statistic / 30
            for m in range(3)
        ]
    )
    assert probability_of_improvement(x, y) == pytest.approx(ref, abs=1e-12)


def test_results_are_python_floats_and_reachable_as_pl_stats() -> None:
    for f in (pl.stats.mean, pl.stats.median, pl.stats.iqm, pl.stats.optimality_gap):
        assert type(f(SCORES)) is float


@pytest.mark.parametrize(
    ("scores", "error", "words"),
    [
        ([], InvalidArgumentError, "empty"),
        (np.zeros((0, 3)), InvalidArgumentError, "empty"),
        (np.zeros((3, 0)), InvalidArgumentError, "empty"),
        (3.0, InvalidArgumentError, "shape ()"),
        (np.zeros((2, 2, 2)), InvalidArgumentError, "shape (2, 2, 2)"),
        ([[1.0, float("nan")], [0.0, 0.0]], NonFiniteError, "scores[0, 1] (run 0, task 1) is nan"),
        ([[1.0, 0.0], [0.0, float("inf")]], NonFiniteError, "scores[1, 1]"),
        ([["a", "b"]], InvalidArgumentError, "dtype <U1"),
        ([[1.0, 2.0], [3.0]], pl.ShapeError, "rows of different lengths"),
    ],
)
def test_bad_scores_raise_policylab_errors(scores: object, error: type, words: str) -> None:
    for f in (mean, median, iqm, optimality_gap):
        with pytest.raises(error) as info:
            f(scores)  # type: ignore[arg-type]
        assert words in str(info.value)


def test_bad_arguments_of_profiles_and_pairs() -> None:
    with pytest.raises(InvalidArgumentError, match="same tasks; x has 2 tasks"):
        probability_of_improvement(np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(NonFiniteError, match=r"y\[0, 0\]"):
        probability_of_improvement(np.zeros((3, 1)), [[float("nan")]])
    with pytest.raises(InvalidArgumentError, match="taus must be a non-empty 1-D"):
        performance_profile(SCORES, [])
    with pytest.raises(NonFiniteError, match=r"taus\[1\] is nan"):
        performance_profile(SCORES, [0.0, float("nan")])
    with pytest.raises(InvalidArgumentError, match="threshold must be a finite number"):
        optimality_gap(SCORES, threshold=float("inf"))
