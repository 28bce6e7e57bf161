"""Monte Carlo: episodes per second of policylab against a plain-Python baseline.

The baseline (``baseline_*`` below) is written the way the common reference notebooks
write Monte Carlo (dictionaries of returns, an episode as a list of (state, action,
reward) tuples, a first-visit search per step), over the Gymnasium environment; it is
ours, written for this comparison, and clearly not policylab code. policylab runs the
compiled kernels on the FiniteMDP (``mc_prediction`` / ``mc_control``) and, for
reference, its own general path (a Python loop over the same Gymnasium env).
Compilation is excluded (one warm-up run first; kernels are cached on disk).
"""

from __future__ import annotations

import sys
import time
from collections import defaultdict
from pathlib import Path

import gymnasium as gym
import numpy as np

import policylab as pl
from policylab.tabular import mc_control, mc_prediction

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_section


# ----------------------------------------------------------------------------- baseline
def baseline_mc_prediction(env, policy_fn, num_episodes, gamma=1.0, seed=0):
    """BASELINE (plain Python, reference-notebook style): first-visit MC prediction of Q."""
    rng = np.random.default_rng(seed)
    returns_sum = defaultdict(float)
    returns_count = defaultdict(float)
    Q = defaultdict(lambda: np.zeros(env.action_space.n))
    env.reset(seed=seed)
    for _ in range(num_episodes):
        episode = []
        state, _ = env.reset()
        while True:
            probs = policy_fn(state)
            action = rng.choice(np.arange(len(probs)), p=probs)
            next_state, reward, terminated, truncated, _ = env.step(action)
            episode.append((state, action, reward))
            if terminated or truncated:
                break
            state = next_state
        sa_in_episode = {(x[0], x[1]) for x in episode}
        for state, action in sa_in_episode:
            first = next(i for i, x in enumerate(episode) if x[0] == state and x[1] == action)
            G = sum(x[2] * (gamma**i) for i, x in enumerate(episode[first:]))
            returns_sum[(state, action)] += G
            returns_count[(state, action)] += 1.0
            Q[state][action] = returns_sum[(state, action)] / returns_count[(state, action)]
    return Q


def baseline_mc_control_epsilon_greedy(env, num_episodes, gamma=1.0, epsilon=0.1, seed=0):
    """BASELINE (plain Python, reference-notebook style): on-policy first-visit MC control."""
    rng = np.random.default_rng(seed)
    n_actions = env.action_space.n
    returns_sum = defaultdict(float)
    returns_count = defaultdict(float)
    Q = defaultdict(lambda: np.zeros(n_actions))

    def policy_fn(observation):
        A = np.ones(n_actions, dtype=float) * epsilon / n_actions
        A[np.argmax(Q[observation])] += 1.0 - epsilon
        return A

    env.reset(seed=seed)
    for _ in range(num_episodes):
        episode = []
        state, _ = env.reset()
        while True:
            probs = policy_fn(state)
            action = rng.choice(np.arange(len(probs)), p=probs)
            next_state, reward, terminated, truncated, _ = env.step(action)
            episode.append((state, action, reward))
            if terminated or truncated:
                break
            state = next_state
        sa_in_episode = {(x[0], x[1]) for x in episode}
        for state, action in sa_in_episode:
            first = next(i for i, x in enumerate(episode) if x[0] == state and x[1] == action)
            G = sum(x[2] * (gamma**i) for i, x in enumerate(episode[first:]))
            returns_sum[(state, action)] += G
            returns_count[(state, action)] += 1.0
            Q[state][action] = returns_sum[(state, action)] / returns_count[(state, action)]
    return Q


# ----------------------------------------------------------------------------- timing
def rate(fn, episodes):
    t0 = time.perf_counter()
    fn(episodes)
    return episodes / (time.perf_counter() - t0)


def runners(mdp, make_env, uniform, model, algo):
    """(policylab compiled, policylab general path, baseline): functions of n episodes."""
    if algo.startswith("first"):

        def ours(n):
            return mc_prediction(mdp, episodes=n, seed=0, checkpoints=10)

        def ours_env(n):
            return mc_prediction(make_env(), episodes=n, seed=0, checkpoints=5, model=model)

        def base(n):
            return baseline_mc_prediction(make_env(), uniform, n)

    else:

        def ours(n):
            return mc_control(mdp, episodes=n, epsilon=0.1, seed=0, checkpoints=10)

        def ours_env(n):
            return mc_control(
                make_env(), episodes=n, epsilon=0.1, seed=0, checkpoints=5, model=model
            )

        def base(n):
            return baseline_mc_control_epsilon_greedy(make_env(), n)

    return ours, ours_env, base


def main() -> None:
    quick = "--quick" in sys.argv
    grid = pl.problems.slippery_gridworld()
    bj = pl.problems.blackjack()
    problems = {
        "slippery gridworld": (
            grid,
            lambda: gym.make("policylab/SlipperyGridworld-v0"),
            np.full(4, 0.25),
            None,
            200_000,
            2_000,
        ),
        "Blackjack": (
            bj,
            lambda: gym.make("Blackjack-v1", sab=True),
            np.full(2, 0.5),
            bj,
            2_000_000,
            20_000,
        ),
    }
    rows = []
    for pname, (mdp, make_env, probs, model, n_ours, n_base) in problems.items():
        if quick:
            n_ours, n_base = n_ours // 20, n_base // 10
        for algo in ("first-visit MC prediction", "epsilon-greedy MC control"):
            ours, ours_env, base = runners(mdp, make_env, lambda s, p=probs: p, model, algo)
            ours(100)  # warm-up: load or compile the kernels
            ours_env(10)
            r_ours = rate(ours, n_ours)
            r_env = rate(ours_env, n_base)
            r_base = rate(base, n_base)
            rows.append((pname, algo, r_ours, r_env, r_base))
            print(
                f"{pname:20s} {algo:28s} ours {r_ours:12,.0f}/s  general path {r_env:9,.0f}/s  "
                f"baseline {r_base:9,.0f}/s  x{r_ours / r_base:,.0f}",
                flush=True,
            )
    lines = [
        "Episodes per second (higher is better). *policylab compiled*: `mc_prediction` / "
        "`mc_control(epsilon=0.1)` on the FiniteMDP (numba kernels, error recorded at 10 "
        "checkpoints). *policylab general path*: the same learners on the Gymnasium env "
        "(Python loop, same compiled update). *Baseline*: plain Python in the style of the "
        "common reference notebooks (dict of returns, first-visit search, `rng.choice` per "
        "step) over the same Gymnasium env (`policylab/SlipperyGridworld-v0`, "
        "`Blackjack-v1` with `sab=True`), written in `benchmarks/bench_mc.py`. Compilation "
        "excluded. Uniform random policy for prediction.",
        "",
        "| problem | algorithm | policylab compiled | policylab general path "
        "| baseline (plain Python) | speed-up vs baseline |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for pname, algo, r_ours, r_env, r_base in rows:
        lines.append(
            f"| {pname} | {algo} | {r_ours:,.0f} | {r_env:,.0f} | {r_base:,.0f} "
            f"| {r_ours / r_base:,.0f}x |"
        )
    if quick:
        print("\n".join(lines))
    else:
        write_section("Monte Carlo", "python benchmarks/bench_mc.py", "\n".join(lines))


if __name__ == "__main__":
    main()
