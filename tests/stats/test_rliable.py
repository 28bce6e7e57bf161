"""Agreement with rliable, the reference implementation, on fixed score matrices.

``rliable_reference.json`` holds score matrices and rliable's point estimates and 95%
stratified bootstrap percentile intervals (written by ``tools/rliable_reference.py`` in
a separate environment: rliable is not a dependency). The two libraries draw different
random resamples, so intervals agree statistically: with 50,000 resamples here and
100,000 there, an endpoint's Monte Carlo error is about 0.001, and 0.01 is over 10
times that.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from policylab.stats import (
    performance_profile,
    performance_profile_ci,
    probability_of_improvement,
    probability_of_improvement_ci,
    summarize,
)

REF = json.loads((Path(__file__).parent / "rliable_reference.json").read_text())
SCORES = {k: np.array(v) for k, v in REF["scores"].items()}
TOL = 0.01


@pytest.mark.parametrize("key", sorted(REF["aggregates"]))
def test_aggregate_intervals_agree_with_rliable(key: str) -> None:
    ours = summarize(SCORES[key], reps=50_000, confidence=REF["confidence"], seed=0)
    for name, ref in REF["aggregates"][key].items():
        assert ours[name]["value"] == pytest.approx(ref["value"], abs=1e-12), (key, name)
        assert ours[name]["low"] == pytest.approx(ref["low"], abs=TOL), (key, name)
        assert ours[name]["high"] == pytest.approx(ref["high"], abs=TOL), (key, name)


def test_the_tolerance_would_catch_an_unstratified_bootstrap() -> None:
    # Resampling the 50 scores of matrix "a" together (mixing tasks) gives a mean
    # interval that misses rliable's by several times the tolerance.
    a = SCORES["a"]
    rng = np.random.default_rng(0)
    pooled = a.ravel()[rng.integers(0, a.size, size=(50_000, *a.shape))].mean(axis=(1, 2))
    low, high = np.quantile(pooled, [0.025, 0.975])
    ref = REF["aggregates"]["a"]["mean"]
    assert abs(low - ref["low"]) > 3 * TOL and abs(high - ref["high"]) > 3 * TOL
    widths = [r["high"] - r["low"] for agg in REF["aggregates"].values() for r in agg.values()]
    assert min(widths) > 5 * TOL


def test_probability_of_improvement_agrees_with_rliable() -> None:
    ref = REF["probability_of_improvement"]
    x, y = SCORES[ref["x"]], SCORES[ref["y"]]
    assert probability_of_improvement(x, y) == pytest.approx(ref["value"], abs=1e-12)
    low, high = probability_of_improvement_ci(x, y, reps=20_000, seed=0)
    assert low == pytest.approx(ref["low"], abs=TOL)
    assert high == pytest.approx(ref["high"], abs=TOL)


def test_performance_profile_agrees_with_rliable() -> None:
    ref = REF["performance_profile"]
    x = SCORES[ref["scores"]]
    np.testing.assert_allclose(performance_profile(x, ref["taus"]), ref["value"], atol=1e-12)
    low, high = performance_profile_ci(x, ref["taus"], reps=20_000, seed=0)
    # a profile takes values k / (runs x tasks), so an endpoint that falls between two of
    # them may land on either: agreement within one step
    step = 1 / x.size
    np.testing.assert_allclose(low, ref["low"], atol=step + 1e-9)
    np.testing.assert_allclose(high, ref["high"], atol=step + 1e-9)
