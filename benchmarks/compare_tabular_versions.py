"""Q-learning, Sarsa and Monte Carlo steps per second for one checkout of policylab.

Run it once per version to compare two versions in turn on the same machine, e.g. an
older commit unpacked with ``git worktree add --detach /tmp/before COMMIT``::

    PYTHONPATH=/tmp/before/src taskset -c 0 .venv/bin/python \\
        benchmarks/compare_tabular_versions.py /tmp/before
    taskset -c 0 .venv/bin/python benchmarks/compare_tabular_versions.py .

It prints the raw kernel (that checkout's ``benchmarks/bench_td.py``), the public API
(best of 3 runs of 200,000 episodes) and ``policylab learn ... FrozenLake8x8-v1
--episodes 1010000 --json`` (gamma 1) in steps per second; the ``learn`` step counts
show whether both versions compute the same runs. Then Monte Carlo control through the
public API (best of 3, CPU time of the thread): FrozenLake 8x8 epsilon-greedy (epsilon
0.1, 200,000 episodes) and blackjack with exploring starts (500,000 episodes), with the
sum of the learned Q as a checksum of the runs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(sys.argv[1] if len(sys.argv) > 1 else ".", "benchmarks"))

import gymnasium as gym

import policylab as pl
from bench_td import kernel_steps
from policylab import tabular
from policylab.tabular import td_kernels as tdk


def main() -> None:
    """Print one line per algorithm and one per ``policylab learn`` run."""
    lake = pl.FiniteMDP.from_gymnasium(
        gym.make("FrozenLake-v1", map_name="8x8"), gamma=0.99, name="FrozenLake8x8"
    )
    learners = ((tdk.Q_LEARNING, "q-learning", tabular.q_learning),
                (tdk.SARSA, "sarsa", tabular.sarsa))  # fmt: skip
    for rule, name, fn in learners:
        kernel_steps(lake, rule, 50)()
        fn(lake, episodes=50)
        raw = pub = 0.0
        for _ in range(3):
            t0 = time.perf_counter()
            n = kernel_steps(lake, rule, 200_000)()
            raw = max(raw, n / (time.perf_counter() - t0))
            r = fn(lake, episodes=200_000, alpha=0.1, epsilon=0.1, seed=0)
            pub = max(pub, r.steps / r.seconds)
        print(f"{name}: raw kernel {raw / 1e6:.2f}M steps/s; public API {pub / 1e6:.2f}M "
              f"steps/s; public / raw {pub / raw:.2f}")  # fmt: skip
        cli = os.path.join(os.path.dirname(sys.executable), "policylab")
        cmd = [cli, "learn", name, "FrozenLake8x8-v1", "--episodes", "1010000", "--json"]
        done = subprocess.run([*cmd, "--seed", "0"], capture_output=True, text=True)
        if done.returncode != 0:
            print(done.stderr[-500:])
            continue
        d = json.loads(done.stdout)
        print(f"  policylab learn {name}: {d['steps'] / d['seconds'] / 1e6:.2f}M steps/s "
              f"({d['steps']} steps, {d['seconds']:.2f} s)")  # fmt: skip


def monte_carlo(lake: pl.FiniteMDP) -> None:
    """One line per Monte Carlo control run: steps per CPU-second and a checksum of Q."""
    runs = (
        ("FrozenLake 8x8, epsilon 0.1", dict(problem=lake, episodes=200_000, epsilon=0.1)),
        ("blackjack, exploring starts",
         dict(problem=pl.problems.blackjack(), episodes=500_000, exploring_starts=True)),
    )  # fmt: skip
    for name, kw in runs:
        tabular.mc_control(**{**kw, "episodes": 50})
        best, r = float("inf"), None
        for _ in range(3):
            t0 = time.thread_time()
            r = tabular.mc_control(**kw, seed=0, score=False)  # type: ignore[arg-type]
            best = min(best, time.thread_time() - t0)
        assert r is not None
        print(f"mc-control, {name}: {r.steps / best / 1e6:.2f}M steps per CPU-second "
              f"({r.steps} steps, {best:.3f} s; sum of Q {float(r.q.sum()):.10g})")  # fmt: skip


if __name__ == "__main__":
    main()
    monte_carlo(
        pl.FiniteMDP.from_gymnasium(
            gym.make("FrozenLake-v1", map_name="8x8"), gamma=0.99, name="FrozenLake8x8"
        )
    )
