"""Sweeps and tuning on Ray Tune: scaling, overhead per trial, and tuning against q*.

Three parts (``python benchmarks/bench_sweep.py [scaling] [overhead] [tuning]``; all by
default; ``--steps N`` sets the PPO budget of the scaling part):

* **scaling**: 8 seeds of PPO on CartPole-v1 as one sweep (8 trials), on a local Ray of
  1 CPU against one of 2 CPUs: wall-clock time of the sweep (Ray's start included and
  also given apart) and the speed-up (target: at least 1.8x on an idle 2-core machine).
* **overhead**: 32 seeds of Q-learning on CliffWalking-v1 (200 episodes each): one
  ``seed_study`` call without Ray, one sweep trial running all 32 seeds at once (what
  ``policylab sweep`` does for tabular algorithms), and 32 trials of one seed each
  (``trial_per_seed=True``): the Ray overhead per trial.
* **tuning**: Q-learning on CliffWalking-v1 scored against the exact q* (minus the RMS
  error of Q, 4 seeds, 200 episodes): its defaults (alpha 0.1, epsilon 0.1), a 16-trial
  TPE search (``policylab tune``) over alpha in [0.05, 1] and epsilon in [0.01, 0.5], and a
  4 x 4 grid search over the same space (``policylab sweep``, 16 configurations). The
  best configuration of each is then re-scored on 16 fresh seeds (100..115), so the
  comparison is not flattered by the selection.

The machine is shared: ``uptime``'s load is recorded with every table.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _report import write_section
from policylab.experiments import sweep, tune
from policylab.experiments.problems import finite_problem, reachable_states
from policylab.tabular import seed_study
from policylab.tabular.truth import GroundTruth


def load() -> str:
    return os.popen("uptime").read().strip()


def timed_ray_sweep(num_cpus: int, **kwargs: object) -> tuple[float, float, dict]:
    """(seconds of ray.init, seconds of the sweep, its sweep.json) on a fresh local Ray."""
    import ray

    t0 = time.perf_counter()
    ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
    t1 = time.perf_counter()
    try:
        doc = sweep(**kwargs)  # type: ignore[arg-type]
    finally:
        t2 = time.perf_counter()
        ray.shutdown()
    return t1 - t0, t2 - t1, doc


def scaling(tmp: Path, steps: int) -> str:
    rows = []
    times = {}
    for cpus in (1, 2):
        init_s, run_s, doc = timed_ray_sweep(
            cpus,
            algorithm="ppo",
            problem="CartPole-v1",
            seeds=8,
            out=tmp / f"ppo-{cpus}",
            options={"steps": steps},
            grid={"torch_threads": [1]},
        )
        done = sum(t["status"] == "TERMINATED" for t in doc["trials"])
        scores = [t["metrics"]["score"] for t in doc["trials"] if t["metrics"].get("score")]
        times[cpus] = run_s
        rows.append(
            f"| {cpus} | {done}/8 | {init_s:.1f} | {run_s:.1f} | {8 * steps / run_s:,.0f} | "
            f"{np.mean(scores):.1f} |"
        )
    body = (
        f"8 seeds of PPO on CartPole-v1, {steps:,} steps each (torch_threads=1), one trial per "
        "seed.\n\n| local Ray CPUs | trials done | ray.init (s) | sweep (s) | env steps/s | "
        "mean score |\n|---:|---:|---:|---:|---:|---:|\n" + "\n".join(rows) + "\n\n"
        f"Speed-up of 2 workers over 1: **{times[1] / times[2]:.2f}x**.\n\nLoad: `{load()}`"
    )
    print(body)
    return body


def overhead(tmp: Path) -> str:
    import ray

    seeds, episodes = 32, 200
    mdp = finite_problem("CliffWalking-v1")
    seed_study("q-learning", mdp, seeds=[0], episodes=10)  # compile once
    t0 = time.perf_counter()
    seed_study("q-learning", mdp, seeds=list(range(seeds)), episodes=episodes, max_steps=10_000)
    plain = time.perf_counter() - t0
    rows = [f"| seed_study, no Ray | 1 call | {plain:.2f} |"]
    seconds = {}
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        common = {
            "algorithm": "q-learning",
            "problem": "CliffWalking-v1",
            "seeds": seeds,
            "options": {"episodes": episodes},
        }
        sweep(out=tmp / "warm", **{**common, "seeds": 2})  # type: ignore[arg-type]
        for per_seed, name in (
            (False, "sweep, seeds in one trial"),
            (True, "sweep, a trial per seed"),
        ):
            t0 = time.perf_counter()
            doc = sweep(out=tmp / f"ov-{per_seed}", trial_per_seed=per_seed, **common)  # type: ignore[arg-type]
            seconds[per_seed] = time.perf_counter() - t0
            n = len({t["tune_trial_id"] for t in doc["trials"]})
            rows.append(f"| {name} | {n} trial(s) | {seconds[per_seed]:.2f} |")
    finally:
        ray.shutdown()
    fixed = seconds[False] - plain
    per_trial = (seconds[True] - seconds[False]) / (seeds - 1)
    body = (
        f"{seeds} seeds of Q-learning on CliffWalking-v1, {episodes} episodes each; a local "
        "Ray of 2 CPUs, already started (its start is not counted).\n\n"
        "| how | trials | seconds |\n|---|---:|---:|\n"
        + "\n".join(rows)
        + f"\n\nFixed cost of one sweep on Ray (Tune's set-up, a worker, the experiment state): "
        f"**{fixed:.1f} s**; each further trial: **{per_trial:.2f} s**, against "
        f"{plain / seeds * 1000:.1f} ms for one tabular run of this size. `policylab sweep` "
        "therefore runs all seeds of a tabular configuration in one trial; deep trials "
        "(minutes each) are one trial per seed.\n\n"
        f"Load: `{load()}`"
    )
    print(body)
    return body


def tuning(tmp: Path) -> str:
    import ray

    mdp = finite_problem("CliffWalking-v1")
    truth = GroundTruth.control(mdp)
    reachable = reachable_states(mdp)
    episodes, fresh = 200, list(range(100, 116))

    def rescore(alpha: float, epsilon: float) -> float:
        runs = seed_study(
            "q-learning", mdp, seeds=fresh, episodes=episodes, alpha=alpha, epsilon=epsilon
        )
        return float(np.mean([-truth.errors(q, None, seen=reachable)[1] for q in runs.q]))

    common = {"seeds": 4, "options": {"episodes": episodes}, "search_seed": 0}
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        t0 = time.perf_counter()
        tuned = tune(
            "q-learning",
            "CliffWalking-v1",
            trials=16,
            space={
                "alpha": {"kind": "uniform", "low": 0.05, "high": 1.0},
                "epsilon": {"kind": "uniform", "low": 0.01, "high": 0.5},
            },
            out=tmp / "tuned",
            **common,  # type: ignore[arg-type]
        )
        tune_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        grid_doc = sweep(
            "q-learning",
            "CliffWalking-v1",
            seeds=4,
            out=tmp / "grid",
            options={"episodes": episodes},
            grid={"alpha": [0.05, 0.35, 0.65, 0.95], "epsilon": [0.01, 0.17, 0.33, 0.5]},
        )
        grid_s = time.perf_counter() - t0
    finally:
        ray.shutdown()
    # the grid's score is the last-10% return: choose its best by the same q* score
    by: dict[str, list[float]] = {}
    cfg: dict[str, dict] = {}
    for t in grid_doc["trials"]:
        by.setdefault(t["config_label"], []).append(-t["metrics"]["reachable_error_rms"])
        cfg[t["config_label"]] = t["config"]
    grid_best = max(by, key=lambda k: np.mean(by[k]))
    best = tuned["best"]
    rows = [
        ("defaults (alpha 0.1, epsilon 0.1)", "-", rescore(0.1, 0.1), "-"),
        (
            f"TPE, 16 trials: {best['config_label']}",
            f"{best['score']:.4f}",
            rescore(best["config"]["alpha"], best["config"]["epsilon"]),
            f"{tune_s:.0f}",
        ),
        (
            f"grid 4 x 4: {grid_best}",
            f"{np.mean(by[grid_best]):.4f}",
            rescore(cfg[grid_best]["alpha"], cfg[grid_best]["epsilon"]),
            f"{grid_s:.0f}",
        ),
    ]
    body = (
        f"Q-learning on CliffWalking-v1, {episodes} episodes; score = minus the RMS error of Q "
        "against the exact q* over the states reachable from the start (higher is better). "
        "Search score: mean over the 4 seeds the search used; fresh: mean over 16 other "
        "seeds (100..115).\n\n"
        "| configuration | search score | fresh-seed score | seconds |\n|---|---:|---:|---:|\n"
        + "\n".join(f"| {a} | {b} | {c:.4f} | {d} |" for a, b, c, d in rows)
        + f"\n\nLoad: `{load()}`"
    )
    print(body)
    return body


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("parts", nargs="*", default=["scaling", "overhead", "tuning"])
    parser.add_argument("--steps", type=int, default=20_000, help="PPO steps per seed (scaling)")
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    try:
        for part in args.parts:
            if part == "scaling":
                cmd = f"python benchmarks/bench_sweep.py scaling --steps {args.steps}"
                write_section(
                    "Sweeps: 8 PPO seeds on 1 and 2 workers", cmd, scaling(tmp, args.steps)
                )
            elif part == "overhead":
                cmd = "python benchmarks/bench_sweep.py overhead"
                write_section("Sweeps: Ray overhead per tabular trial", cmd, overhead(tmp))
            elif part == "tuning":
                cmd = "python benchmarks/bench_sweep.py tuning"
                write_section("Tuning Q-learning against q*", cmd, tuning(tmp))
            else:
                parser.error(f"unknown part {part!r}; parts: scaling, overhead, tuning")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
