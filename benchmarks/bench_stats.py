"""Bootstrap confidence intervals: policylab.stats against scipy and a per-resample loop.

Anchors, in the same run and on the same score matrices:

- ``scipy.stats.bootstrap`` (vectorised, percentile method) on one task, where plain
  resampling and the stratified bootstrap are the same thing; it cannot stratify, so it
  is left out for several tasks;
- a per-resample Python loop (``loop_ci`` below: draw indices per task, call the
  statistic, as rliable does through arch's bootstrap), ours, written for this
  comparison.

Each row gives the seconds of one interval of the IQM (``scipy.stats.trim_mean(x, 0.25)``
over all scores) and the interval itself, so that agreement is visible beside speed.
The loop runs fewer resamples (its time scales linearly; the column says how many).

    .venv/bin/python benchmarks/bench_stats.py [--reps 50000] [--write]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import scipy.stats

import policylab as pl

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_section


def loop_ci(scores: np.ndarray, reps: int, seed: int) -> tuple[float, float]:
    """BASELINE: one stratified resample and one statistic call per repetition."""
    rng = np.random.default_rng(seed)
    n, m = scores.shape
    values = np.empty(reps)
    for b in range(reps):
        idx = rng.integers(0, n, size=(n, m))
        values[b] = scipy.stats.trim_mean(scores[idx, np.arange(m)], 0.25, axis=None)
    lo, hi = np.quantile(values, [0.025, 0.975])
    return float(lo), float(hi)


def scipy_ci(scores: np.ndarray, reps: int, seed: int) -> tuple[float, float]:
    """scipy.stats.bootstrap of the IQM of one task (percentile method, vectorised)."""
    res = scipy.stats.bootstrap(
        (scores[:, 0],),
        lambda x, axis: scipy.stats.trim_mean(x, 0.25, axis=axis),
        n_resamples=reps,
        method="percentile",
        vectorized=True,
        random_state=np.random.default_rng(seed),
    )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def rliable_agreement(reps: int) -> str:
    """Largest gap between policylab's intervals and rliable's stored ones (the test fixture)."""
    import json

    path = Path(__file__).resolve().parent.parent / "tests" / "stats" / "rliable_reference.json"
    ref = json.loads(path.read_text())
    gaps: dict[str, float] = {}
    for key, aggs in ref["aggregates"].items():
        ours = pl.stats.summarize(np.array(ref["scores"][key]), reps=reps, seed=0)
        for name, r in aggs.items():
            gap = max(abs(ours[name]["low"] - r["low"]), abs(ours[name]["high"] - r["high"]))
            gaps[name] = max(gaps.get(name, 0.0), gap)
    poi = ref["probability_of_improvement"]
    low, high = pl.stats.probability_of_improvement_ci(
        np.array(ref["scores"][poi["x"]]), np.array(ref["scores"][poi["y"]]), reps=20_000, seed=0
    )
    gaps["probability_of_improvement"] = max(abs(low - poi["low"]), abs(high - poi["high"]))
    made = ref["produced_by"]
    return (
        f"Agreement with rliable {made['rliable']} (stored by `tools/rliable_reference.py`, "
        f"{made['reps']['aggregates']:,} resamples there, {reps:,} here; "
        f"{len(ref['aggregates'])} score matrices): largest endpoint gap per statistic "
        + ", ".join(f"{k} {v:.4f}" for k, v in gaps.items())
        + f". rliable took {made['seconds']} s for its reference run (Python loop per "
        "resample), on this machine under load (load average about 6)."
    )


def timed(fn, *args, **kwargs) -> tuple[float, tuple[float, float]]:
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return time.perf_counter() - t0, out


def main() -> int:
    """Print the table (and with ``--write`` put it into BENCHMARKS.md)."""
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=50_000)
    parser.add_argument("--loop-reps", type=int, default=5_000)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    shapes = [(10, 1), (100, 1), (10, 5), (10, 57), (100, 20)]
    rows = [
        "| scores (runs x tasks) | policylab s | policylab CI | scipy s | scipy CI "
        f"| loop s ({args.loop_reps:,} reps) | loop s scaled to {args.reps:,} | loop CI |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for shape in shapes:
        x = rng.gamma(2.0, 0.3, size=shape)
        pl.stats.bootstrap_ci(x, pl.stats.iqm, reps=100, seed=0)  # warm-up
        t_pl, ci_pl = timed(pl.stats.bootstrap_ci, x, pl.stats.iqm, reps=args.reps, seed=0)
        if shape[1] == 1:
            t_sp, ci_sp = timed(scipy_ci, x, args.reps, 0)
            sp = f"{t_sp:.2f} | [{ci_sp[0]:.4f}, {ci_sp[1]:.4f}]"
        else:
            sp = "- | (cannot stratify)"
        t_lp, ci_lp = timed(loop_ci, x, args.loop_reps, 0)
        scaled = t_lp * args.reps / args.loop_reps
        rows.append(
            f"| {shape[0]} x {shape[1]} | {t_pl:.2f} | [{ci_pl[0]:.4f}, {ci_pl[1]:.4f}] | {sp} "
            f"| {t_lp:.2f} | {scaled:.1f} | [{ci_lp[0]:.4f}, {ci_lp[1]:.4f}] |"
        )
        print(rows[-1], flush=True)
    load = os.getloadavg()
    body = (
        f"95% percentile interval of the IQM, {args.reps:,} resamples (policylab, scipy). "
        f"Load average while measuring: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on 2 cores "
        "shared with other work, so the seconds are noisy; the ratios between columns of a "
        "row are what to read.\n\n" + "\n".join(rows)
    )
    body += "\n\n" + rliable_agreement(args.reps)
    print(body)
    if args.write:
        write_section(
            "Statistics: bootstrap intervals",
            f".venv/bin/python benchmarks/bench_stats.py --reps {args.reps} --write",
            body,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
