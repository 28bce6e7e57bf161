"""Write rliable's interval estimates on fixed score matrices: the fixture of tests/stats.

rliable (Agarwal et al. 2021, "Deep Reinforcement Learning at the Edge of the
Statistical Precipice") is the reference implementation of policylab.stats, but it is
not a dependency (it needs pandas < 3). Run this once in a separate environment::

    python3 -m venv /tmp/rlenv && /tmp/rlenv/bin/pip install rliable 'pandas<3'
    /tmp/rlenv/bin/python tools/rliable_reference.py tests/stats/rliable_reference.json

It draws fixed score matrices (seeded), rounds them to 6 decimals, and stores them with
rliable's point estimates and 95% percentile intervals (stratified bootstrap) of the
median, IQM, mean and optimality gap, the probability of improvement of one matrix
over another, and a performance profile. ``tests/stats/test_rliable.py`` checks that
policylab's intervals agree within 0.01.
"""

from __future__ import annotations

import json
import platform
import sys
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np

REPS = 100_000  # aggregates: rliable loops in Python, about a minute per matrix
REPS_PAIR = 20_000  # probability of improvement: a Mann-Whitney U test per task per resample
REPS_PROFILE = 20_000
TAUS = [0.25, 0.5, 0.75, 1.0]


def matrices() -> dict[str, np.ndarray]:
    """The fixed score matrices: two algorithms on 5 tasks and one single-task sweep."""
    rng = np.random.default_rng(2021)
    difficulty = np.array([0.9, 0.7, 0.5, 0.8, 0.3])
    a = np.clip(rng.normal(difficulty, 0.2, size=(10, 5)), 0.0, 1.2)
    b = np.clip(rng.normal(difficulty - 0.1, 0.25, size=(12, 5)), 0.0, 1.2)
    single = rng.gamma(2.0, 0.3, size=(25, 1))  # skewed: IQM and mean differ
    return {k: np.round(v, 6) for k, v in {"a": a, "b": b, "single": single}.items()}


def main() -> int:
    """Compute the reference and write it to the path given (or print it)."""
    from rliable import library, metrics

    scores = matrices()

    def aggregates(x: np.ndarray) -> np.ndarray:
        return np.array(
            [
                metrics.aggregate_median(x),
                metrics.aggregate_iqm(x),
                metrics.aggregate_mean(x),
                metrics.aggregate_optimality_gap(x),
            ]
        )

    names = ["median", "iqm", "mean", "optimality_gap"]
    start = time.time()
    np.random.seed(0)  # rliable's StratifiedBootstrap draws from NumPy's global RNG
    points, intervals = library.get_interval_estimates(
        scores, aggregates, reps=REPS, confidence_interval_size=0.95
    )
    out: dict[str, object] = {
        "scores": {k: v.tolist() for k, v in scores.items()},
        "confidence": 0.95,
        "aggregates": {
            key: {
                name: {
                    "value": float(points[key][i]),
                    "low": float(intervals[key][0, i]),
                    "high": float(intervals[key][1, i]),
                }
                for i, name in enumerate(names)
            }
            for key in scores
        },
    }
    np.random.seed(1)
    pair_points, pair_intervals = library.get_interval_estimates(
        {"a,b": [scores["a"], scores["b"]]},
        lambda x, y: np.array([metrics.probability_of_improvement(x, y)]),
        reps=REPS_PAIR,
    )
    out["probability_of_improvement"] = {
        "x": "a",
        "y": "b",
        "value": float(pair_points["a,b"][0]),
        "low": float(pair_intervals["a,b"][0, 0]),
        "high": float(pair_intervals["a,b"][1, 0]),
    }
    np.random.seed(2)
    profiles, profile_cis = library.create_performance_profile(
        {"a": scores["a"]}, TAUS, reps=REPS_PROFILE
    )
    out["performance_profile"] = {
        "scores": "a",
        "taus": TAUS,
        "value": profiles["a"].tolist(),
        "low": profile_cis["a"][0].tolist(),
        "high": profile_cis["a"][1].tolist(),
    }
    out["produced_by"] = {
        "script": "tools/rliable_reference.py",
        "rliable": version("rliable"),
        "arch": version("arch"),
        "numpy": np.__version__,
        "python": platform.python_version(),
        "reps": {"aggregates": REPS, "probability_of_improvement": REPS_PAIR},
        "reps_profile": REPS_PROFILE,
        "seconds": round(time.time() - start, 1),
    }
    text = json.dumps(out, indent=1) + "\n"
    if len(sys.argv) > 1:
        Path(sys.argv[1]).write_text(text)
        print(f"wrote {sys.argv[1]} in {out['produced_by']['seconds']} s")  # type: ignore[index]
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
