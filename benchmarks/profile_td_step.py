"""What one Q-learning / Sarsa step on FrozenLake 8x8 costs, piece by piece (one core).

Each piece of the one-step control kernel's step is timed alone in a compiled loop of
N calls over the same arrays the kernel reads (numba microbenchmarks, compiled as the
episode loops are: ``td_kernels.episode_loop``, without reference counting): the RNG draw,
sampling the next state from the model, the epsilon-greedy action (with its random
tie-break), the Q-learning target's max, the step-size schedule; then the whole
kernel, the public API (error against q* at 50 checkpoints) and the public API with
one checkpoint, in the same run. Nanoseconds of CPU time per call (``time.thread_time``:
on a loaded machine the time the process waits for a core is not counted), best of 5.

Run: ``python benchmarks/profile_td_step.py`` (prints a Markdown table).
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import policylab as pl
from policylab import tabular
from policylab.tabular.kernels import (
    KernelMDP,
    epsilon_greedy_at,
    rand_uniform,
    rng_states,
    sample_next,
)
from policylab.tabular.rules.td import q_learning_target
from policylab.tabular.schedules import Schedule, schedule_value
from policylab.tabular.td_kernels import episode_loop

N = 2_000_000


@episode_loop
def _draws(rng, n):  # type: ignore[no-untyped-def]
    acc = 0.0
    for _ in range(n):
        acc += rand_uniform(rng)
    return acc


@episode_loop
def _next(indptr, cdf, rng, n, n_rows):  # type: ignore[no-untyped-def]
    acc = 0
    row = 0
    for _ in range(n):
        acc += sample_next(indptr, cdf, row, rng)
        row += 7
        if row >= n_rows:
            row -= n_rows
    return acc


@episode_loop
def _eps_greedy(q, mask, rng, n):  # type: ignore[no-untyped-def]
    acc = 0
    s = 0
    S = q.shape[0]
    for _ in range(n):
        acc += epsilon_greedy_at(q, mask, s, 0.1, rng)
        s += 5
        if s >= S:
            s -= S
    return acc


@episode_loop
def _max_target(q, mask, n):  # type: ignore[no-untyped-def]
    acc = 0.0
    s = 0
    S = q.shape[0]
    for _ in range(n):
        acc += q_learning_target(0.0, 0.99, q, mask, s, False)
        s += 5
        if s >= S:
            s -= S
    return acc


@episode_loop
def _schedule(params, n):  # type: ignore[no-untyped-def]
    acc = 0.0
    for i in range(n):
        acc += schedule_value(params, float(i % 97 + 1))
    return acc


def _ns(fn, n: int) -> float:  # type: ignore[no-untyped-def]
    fn()
    best = float("inf")
    for _ in range(5):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best / n * 1e9


def main() -> None:
    load0 = os.getloadavg()[0]
    env = gym.make("FrozenLake-v1", map_name="8x8")
    lake = pl.FiniteMDP.from_gymnasium(env, gamma=0.99, name="FrozenLake8x8")
    km = KernelMDP.of(lake)
    S, A = lake.n_states, lake.n_actions
    rng = rng_states(0, 1)[0]
    q_learned = tabular.q_learning(lake, episodes=20_000, seed=0).q.copy()  # realistic Q
    q_zero = np.zeros((S, A))
    mask = km.mask
    rows: list[tuple[str, float]] = [
        ("one uniform draw (xoshiro256+)", _ns(lambda: _draws(rng, N), N)),
        (
            "next state from the model (3 outcomes a row)",
            _ns(lambda: _next(km.indptr, km.cdf, rng, N, S * A), N),
        ),
        (
            "epsilon-greedy action, learned Q (few ties)",
            _ns(lambda: _eps_greedy(q_learned, mask, rng, N), N),
        ),
        (
            "epsilon-greedy action, Q = 0 (all tied)",
            _ns(lambda: _eps_greedy(q_zero, mask, rng, N), N),
        ),
        ("Q-learning target max_a Q(S', a)", _ns(lambda: _max_target(q_learned, mask, N), N)),
        (
            "step size schedule (constant)",
            _ns(lambda: _schedule(Schedule.constant(0.1).params, N), N),
        ),
    ]
    for name, learner in (("Q-learning", tabular.q_learning), ("Sarsa", tabular.sarsa)):
        learner(lake, episodes=50)
        best_pub = best_one = float("inf")
        for _ in range(3):
            t0 = time.thread_time()
            res = learner(lake, episodes=100_000, seed=0)
            best_pub = min(best_pub, (time.thread_time() - t0) / res.steps * 1e9)
            t0 = time.thread_time()
            res = learner(lake, episodes=100_000, seed=0, checkpoints=1)
            best_one = min(best_one, (time.thread_time() - t0) / res.steps * 1e9)
        rows.append((f"{name}: a whole step, public API, error at 50 checkpoints", best_pub))
        rows.append((f"{name}: a whole step, public API, error at the end only", best_one))
    print(
        f"Cost of the pieces of a step, FrozenLake 8x8 (slippery), one core, ns per call, "
        f"best of 5; load average {load0:.1f} -> {os.getloadavg()[0]:.1f} on 2 cores."
    )
    print()
    print("| piece | ns |")
    print("|---|---:|")
    for name, ns in rows:
        print(f"| {name} | {ns:.1f} |")


if __name__ == "__main__":
    main()
