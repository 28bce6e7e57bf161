"""Temporal-difference learning: environment steps per second, and seeds per second.

* Q-learning and Sarsa on FrozenLake 8x8 (slippery), one core: policylab's compiled
  kernel, policylab's general path (the same kernel source run as Python over
  Gymnasium's env), a plain Python loop over Gymnasium's FrozenLake written here
  (``plain_gymnasium_q_learning``, clearly not policylab), and, where the ``bench`` extra
  is installed, pymdptoolbox's ``QLearning`` (hiive fork) on the same model.
* The public API (``q_learning``/``sarsa``, error tracking on) and ``policylab learn``
  against the raw kernel, in the same run.
* A 200-seed cliff-walking study (Sarsa, epsilon 0.1, alpha 0.5, 500 episodes per seed)
  in one compiled call: ``python benchmarks/bench_td.py --study`` prints only it, to
  compare ``taskset -c 0`` (one core) with both cores; the checksum of the returns
  must be the same.

Every figure is the best of a few repeats after a warm-up (numba compiles once and
caches on disk). Run: ``python benchmarks/bench_td.py`` (or ``make bench``).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import policylab as pl
from policylab import tabular
from policylab.tabular import td_kernels as tdk
from policylab.tabular.common import GymStepper, StateIndex
from policylab.tabular.kernels import KernelMDP, rng_states
from policylab.tabular.schedules import Schedule

sys.path.insert(0, os.path.dirname(__file__))
from _report import write_section

REPEATS = 4


def best_of(fn: Callable[[], int], repeats: int = REPEATS) -> tuple[float, int]:
    """(best steps per second, steps of one repeat)."""
    best, steps = 0.0, 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        steps = fn()
        dt = time.perf_counter() - t0
        best = max(best, steps / dt)
    return best, steps


def plain_gymnasium_q_learning(env: Any, n_steps: int, sarsa: bool, seed: int = 0) -> int:
    """A plain Python loop over Gymnasium's FrozenLake: epsilon-greedy tabular Q-learning
    (or Sarsa) with NumPy, the way a tutorial writes it. Not policylab code."""
    rng = np.random.default_rng(seed)
    q = np.zeros((env.observation_space.n, env.action_space.n))
    alpha, gamma, eps = 0.1, 0.99, 0.1
    s, _ = env.reset(seed=seed)
    a = int(rng.integers(4)) if rng.random() < eps else int(np.argmax(q[s]))
    for _ in range(n_steps):
        s2, r, term, trunc, _ = env.step(a)
        a2 = int(rng.integers(4)) if rng.random() < eps else int(np.argmax(q[s2]))
        target = r if term else r + gamma * (q[s2, a2] if sarsa else q[s2].max())
        q[s, a] += alpha * (target - q[s, a])
        if term or trunc:
            s, _ = env.reset()
            a = int(rng.integers(4)) if rng.random() < eps else int(np.argmax(q[s]))
        else:
            s, a = s2, a2
    return n_steps


def kernel_steps(
    mdp: pl.FiniteMDP, rule: int, episodes: int, *, python: bool = False
) -> Callable[[], int]:
    """One call of the episode loop of one-step control, compiled or over Gymnasium."""
    S, A = mdp.n_states, mdp.n_actions
    km = KernelMDP.of(mdp)
    alpha, eps = Schedule.constant(0.1).params, Schedule.constant(0.1).params

    def run() -> int:
        q1 = np.zeros((S, A))
        tables = tdk.Tables(
            q1,
            q1,
            q1,
            np.zeros((S, A), dtype=np.int64),
            np.zeros((S, A)),
            np.zeros((0, 0), dtype=np.int64),
            np.zeros((0, 0)),
            np.zeros(1, dtype=np.int64),
            np.zeros((0, 0)),
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
            np.zeros(0),
        )
        out = tdk.Episodes(
            np.zeros(episodes),
            np.zeros(episodes, dtype=np.int64),
            np.zeros(episodes, dtype=np.int64),
        )
        settings = tdk.Settings(0.99, alpha, eps, 100_000, rule, 1, 0.0, 0, 0, True)
        rng = rng_states(0, 1)[0]
        if python:
            env: Any = GymStepper(pl.MDPEnv(mdp), StateIndex.discrete(S), 0)
            model = tdk.model_tuple(None, km.mask)
            fn = tdk.run_kernel.py_func
        else:
            env, model = None, tdk.model_tuple(km)
            fn = tdk.run_kernel
        return int(fn(tdk.ONE_STEP, env, model, tables, settings, out, rng, 0, episodes))

    return run


def mdptoolbox_steps(mdp: pl.FiniteMDP, n_iter: int) -> Callable[[], int] | None:
    """pymdptoolbox (hiive) QLearning on the same model, if the bench extra is installed."""
    try:
        from hiive.mdptoolbox.mdp import QLearning
    except ImportError:
        try:
            from mdptoolbox.mdp import QLearning  # type: ignore[no-redef]
        except ImportError:
            return None
    P = [mdp.transitions(a).toarray() for a in mdp.actions]
    for p in P:  # terminal rows: stay (pymdptoolbox needs stochastic rows)
        p[mdp.terminal, :] = 0.0
        p[np.flatnonzero(mdp.terminal), np.flatnonzero(mdp.terminal)] = 1.0
    R = np.asarray(mdp.expected_reward)

    def run() -> int:
        np.random.seed(0)
        QLearning(P, R, 0.99, n_iter=n_iter).run()
        return n_iter

    return run


def public_vs_raw(lake: pl.FiniteMDP) -> list[tuple[str, float, float, float]]:
    """(algorithm, raw kernel, public API, ``policylab learn``) steps/s, best of repeats."""
    out = []
    for rule, name, learner in (
        (tdk.Q_LEARNING, "q-learning", tabular.q_learning),
        (tdk.SARSA, "sarsa", tabular.sarsa),
    ):
        kernel_steps(lake, rule, 50)()
        learner(lake, episodes=50)
        raw = pub = 0.0
        for _ in range(REPEATS):
            r, _n = best_of(kernel_steps(lake, rule, 100_000), repeats=1)
            res = learner(lake, episodes=100_000, alpha=0.1, epsilon=0.1, seed=0)
            raw, pub = max(raw, r), max(pub, res.steps / res.seconds)
        cmd = [
            os.path.join(os.path.dirname(sys.executable), "policylab"),
            *("learn", name, "FrozenLake8x8-v1", "--episodes", "100000", "--json"),
        ]
        done = subprocess.run(cmd, capture_output=True, text=True, check=True)
        got = json.loads(done.stdout)
        out.append((name, raw, pub, got["steps"] / got["seconds"]))
    return out


def seed_study_row(n_seeds: int, repeats: int = 1) -> tuple[int, int, float, float, str, int]:
    """One many-seed study: (seeds, steps, best seconds of ``repeats``, mean return,
    checksum, threads)."""
    import hashlib

    import numba

    cliff = pl.problems.cliff_walking()
    tabular.seed_study("sarsa", cliff, 2, episodes=10)  # warm-up (load the compiled loop)
    dt = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        study = tabular.seed_study(
            "sarsa", cliff, n_seeds, seed=0, episodes=500, alpha=0.5, epsilon=0.1
        )
        dt = min(dt, time.perf_counter() - t0)
    checksum = hashlib.sha256(study.returns.tobytes()).hexdigest()[:12]
    return n_seeds, study.steps, dt, study.mean_return(100), checksum, numba.get_num_threads()


def study_only(n_seeds: int = 200) -> None:
    """``--study [N]``: only the N-seed study, best of 5 calls (to compare ``taskset -c 0``
    with both cores)."""
    n_seeds, steps, dt, mean, checksum, threads = seed_study_row(n_seeds, repeats=5)
    print(
        f"{n_seeds} seeds x 500 episodes: {steps:,} steps in {dt:.3f} s, best of 5 "
        f"({steps / dt:,.0f} "
        f"steps/s, {threads} threads, {len(os.sched_getaffinity(0))} cores allowed); mean "
        f"reward {mean:.2f}; checksum {checksum}"
    )


def main() -> None:
    load0 = os.getloadavg()[0]
    lake_env = gym.make("FrozenLake-v1", map_name="8x8")
    lake = pl.FiniteMDP.from_gymnasium(lake_env, gamma=0.99, name="FrozenLake8x8")
    rows: list[tuple[str, str, float, int]] = []
    for rule, name in ((tdk.Q_LEARNING, "Q-learning"), (tdk.SARSA, "Sarsa")):
        kernel_steps(lake, rule, 50)()  # warm-up (load the compiled kernel)
        # Compiled and plain loop alternate, so that both see the same machine load.
        fast = plain = 0.0
        n_fast = n_plain = 0
        for _ in range(REPEATS):
            f, n_fast = best_of(kernel_steps(lake, rule, 100_000), repeats=1)
            p, n_plain = best_of(
                lambda r=rule: plain_gymnasium_q_learning(lake_env, 100_000, sarsa=r == tdk.SARSA),
                repeats=1,
            )
            fast, plain = max(fast, f), max(plain, p)
        general, n_gen = best_of(kernel_steps(lake, rule, 1_000, python=True), repeats=1)
        rows += [
            (name, "policylab, compiled kernel (FiniteMDP)", fast, n_fast),
            (name, "policylab, general path (same kernel as Python, over MDPEnv)", general, n_gen),
            (
                name,
                "plain Python loop over gymnasium FrozenLake (benchmarks/bench_td.py)",
                plain,
                n_plain,
            ),
        ]
        if rule == tdk.Q_LEARNING:
            tb = mdptoolbox_steps(lake, 200_000)
            if tb is not None:
                anchor, n_anchor = best_of(tb, repeats=1)
                rows.append(
                    (name, "anchor: pymdptoolbox-hiive QLearning (same model)", anchor, n_anchor)
                )
        ratio = fast / plain
        rows.append((name, f"ratio compiled / plain loop: {ratio:,.0f}x", float("nan"), 0))

    public_rows = public_vs_raw(lake)
    lines = [
        "Environment steps per second on FrozenLake 8x8 (slippery), one core, epsilon 0.1, "
        "alpha 0.1, gamma 0.99 (best of repeats; target: >= 10 million/s and >= 200x the "
        f"plain loop). Load average during the run: {load0:.1f} -> {os.getloadavg()[0]:.1f} "
        "on 2 cores (above 1, other work shared the machine: figures are lower and noisier). "
        "The plain loop's own speed varies by up to 1.5x between runs, and the ratio with it.",
        "",
        "| algorithm | implementation | steps/s | steps timed |",
        "|---|---|---:|---:|",
    ]
    for algo, impl, rate, n in rows:
        if np.isnan(rate):
            lines.append(f"| {algo} | **{impl}** | | |")
        else:
            lines.append(f"| {algo} | {impl} | {rate:,.0f} | {n:,} |")
    lines += [
        "",
        "The public path against the raw kernel, alternating in the same run (error against "
        "q* recorded at 50 checkpoints, as users run it; `policylab learn` is FrozenLake8x8-v1 "
        "with its own gamma 1):",
        "",
        "| algorithm | raw kernel steps/s | public API steps/s | public / raw | "
        "`policylab learn` steps/s |",
        "|---|---:|---:|---:|---:|",
    ]
    for algo, raw, pub, cli in public_rows:
        lines.append(f"| {algo} | {raw:,.0f} | {pub:,.0f} | {pub / raw:.2f} | {cli:,.0f} |")
    study_rows = [seed_study_row(200)]
    lines += [
        "",
        "Many seeds in one compiled call: cliff-walking Sarsa (epsilon 0.1, alpha 0.5, 500 "
        "episodes per seed), `policylab.tabular.seed_study` (numba prange over seeds; "
        f"{study_rows[0][5]} threads here). The checksum of all returns is the same for any "
        "thread count and any core set.",
        "",
        "| seeds | episodes | steps | seconds | seeds/s | steps/s | mean reward/episode "
        "(101-500) | checksum |",
        "|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for n_seeds, steps, dt, mean, checksum, _ in study_rows:
        lines.append(
            f"| {n_seeds} | 500 | {steps:,} | {dt:.3f} | {n_seeds / dt:,.0f} | "
            f"{steps / dt:,.0f} | {mean:.1f} | {checksum} |"
        )
    body = "\n".join(lines)
    print(body)
    write_section("Temporal-difference", "python benchmarks/bench_td.py", body)


if __name__ == "__main__":
    if "--study" in sys.argv[1:]:
        rest = sys.argv[sys.argv.index("--study") + 1 :]
        study_only(int(rest[0]) if rest else 200)
    else:
        main()
