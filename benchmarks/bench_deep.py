"""Deep RL: policylab's PPO and DQN against Stable-Baselines3 with rl-baselines3-zoo settings.

For every (algorithm, environment) and seed, both libraries train on the same machine in
the same run, one after the other (seed by seed, so both see the same load), each with
torch limited to one thread. Every ``eval_every`` steps the current policy is evaluated
greedily on 100 episodes (evaluation time is not counted as training time); the
environment counts as solved once that mean reaches the threshold (CartPole-v1 475,
Acrobot-v1 -100, LunarLander-v3 200).

- policylab trains with ``policylab train``'s defaults (``pl.deep.default_config``) and
  stops at the first solved evaluation: its time is the wall-clock time to solve.
- Stable-Baselines3 trains its whole zoo budget (as the issue's baseline asks: "trains at
  its budget"); its table row gives that full time, whether the last evaluation solved
  the task, and also the time at which an evaluation first reached the threshold.

With ``--full-budget`` policylab also trains its whole budget (the time to solve is then
the training time until its first solved evaluation, as for SB3), so that the final
returns of both libraries at the same budget can be compared.

Usage: ``python benchmarks/bench_deep.py [--seeds 5] [--envs CartPole-v1,Acrobot-v1]
[--algos ppo,dqn] [--full-budget]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import torch

import policylab as pl
from policylab.deep.common.evaluation import run_episodes
from policylab.deep.zoo import zoo_settings

THRESHOLD = {"CartPole-v1": 475.0, "Acrobot-v1": -100.0, "LunarLander-v3": 200.0}
EVAL_EVERY = {"CartPole-v1": 5_000, "Acrobot-v1": 10_000, "LunarLander-v3": 50_000}


@dataclass
class Result:
    library: str
    algo: str
    env_id: str
    seed: int
    budget: int
    train_seconds: float = 0.0  # training time only (evaluations excluded)
    steps: int = 0
    solve_seconds: float | None = None  # training time until the first solved evaluation
    solve_steps: int | None = None
    final_mean: float = float("nan")
    evals: list[tuple[int, float]] = field(default_factory=list)


class _Clock:
    """Training time with evaluation pauses taken out."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.paused = 0.0

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0 - self.paused

    def pause(self, seconds: float) -> None:
        self.paused += seconds


def _evaluate(act: Any, env_id: str, seed: int) -> float:
    return float(np.mean(run_episodes(act, env_id, 100, seed=10_000 + seed, n_envs=100)))


def run_policylab(algo: str, env_id: str, seed: int, full_budget: bool = False) -> Result:
    fields, budget = pl.deep.default_config(algo, env_id)
    assert budget is not None
    res = Result("policylab", algo, env_id, seed, budget)
    agent = pl.deep.ALGORITHMS[algo](env_id, seed=seed, **fields)
    every, thr = EVAL_EVERY[env_id], THRESHOLD[env_id]
    nxt = [every]
    clock = _Clock()

    def cb(a: pl.deep.Agent, _: dict[str, float]) -> bool | None:
        if a.num_timesteps < nxt[0]:
            return None
        nxt[0] += every
        t = clock.elapsed()
        t_eval = time.perf_counter()
        mean = _evaluate(lambda o: a.predict(o, deterministic=True), env_id, seed)
        clock.pause(time.perf_counter() - t_eval)
        res.evals.append((a.num_timesteps, mean))
        if mean >= thr and res.solve_steps is None:
            res.solve_seconds, res.solve_steps = t, a.num_timesteps
            return None if full_budget else False
        return None

    agent.learn(budget, callback=cb)
    res.train_seconds, res.steps = clock.elapsed(), agent.num_timesteps
    res.final_mean = (
        res.evals[-1][1]
        if res.solve_steps and not full_budget
        else _evaluate(lambda o: agent.predict(o, deterministic=True), env_id, seed)
    )
    return res


def _linear(v: float) -> Any:
    return lambda progress_remaining: progress_remaining * v


def run_sb3(algo: str, env_id: str, seed: int, full_budget: bool = True) -> Result:
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    z = zoo_settings(algo, env_id)
    budget = int(z.pop("steps"))
    res = Result("SB3 (zoo)", algo, env_id, seed, budget)
    normalize = z.pop("normalize", False)
    n_envs = int(z.pop("n_envs", 1))
    hidden = z.pop("hidden", None)
    anneal = z.pop("anneal_lr", False)
    venv = make_vec_env(env_id, n_envs=n_envs, seed=seed)
    if normalize:
        venv = VecNormalize(venv, gamma=z.get("gamma", 0.99))
    kwargs: dict[str, Any] = dict(z)
    if algo == "ppo":
        lr = kwargs.pop("learning_rate", 3e-4)
        kwargs["learning_rate"] = _linear(lr) if anneal else lr
        if anneal:
            kwargs["clip_range"] = _linear(kwargs.get("clip_range", 0.2))
        model: Any = PPO("MlpPolicy", venv, seed=seed, device="cpu", **kwargs)
    else:
        if hidden is not None:
            kwargs["policy_kwargs"] = {"net_arch": list(hidden)}
        model = DQN("MlpPolicy", venv, seed=seed, device="cpu", **kwargs)
    every, thr = EVAL_EVERY[env_id], THRESHOLD[env_id]
    clock = _Clock()

    def act(obs: np.ndarray) -> np.ndarray:
        if normalize:
            obs = venv.normalize_obs(obs)
        return model.predict(obs, deterministic=True)[0]

    class Eval(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.next = every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += every
                t = clock.elapsed()
                t_eval = time.perf_counter()
                mean = _evaluate(act, env_id, seed)
                clock.pause(time.perf_counter() - t_eval)
                res.evals.append((self.num_timesteps, mean))
                if mean >= thr and res.solve_steps is None:
                    res.solve_seconds, res.solve_steps = t, self.num_timesteps
            return True

    clock = _Clock()
    model.learn(budget, callback=Eval())
    res.train_seconds, res.steps = clock.elapsed(), budget
    res.final_mean = _evaluate(act, env_id, seed)
    venv.close()
    return res


def _fmt(xs: list[float]) -> str:
    if not xs:
        return "-"
    if len(xs) == 1:
        return f"{xs[0]:.1f}"
    return f"{statistics.median(xs):.1f} ({min(xs):.1f}-{max(xs):.1f})"


def table(results: list[Result], full_budget: bool = False) -> str:
    rows = [
        "| algorithm | env | library | budget (steps) | seeds solved "
        "| time to solve, s: median (range) | training time at budget or to solve, s "
        "| steps to solve (median) | final 100-episode mean |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    keys = sorted({(r.algo, r.env_id) for r in results}, key=lambda k: (k[1], k[0]))
    for algo, env_id in keys:
        for lib in ("policylab", "SB3 (zoo)"):
            rs = [r for r in results if (r.algo, r.env_id, r.library) == (algo, env_id, lib)]
            if not rs:
                continue
            thr = THRESHOLD[env_id]
            if lib == "policylab" and not full_budget:
                solved = [r for r in rs if r.solve_steps is not None]
                n_solved = f"{len(solved)}/{len(rs)}"
            else:
                solved = [r for r in rs if r.solve_steps is not None]
                at_end = sum(r.final_mean >= thr for r in rs)
                n_solved = (
                    f"{at_end}/{len(rs)} at budget ({len(solved)}/{len(rs)} at some evaluation)"
                )
            rows.append(
                f"| {algo.upper()} | {env_id} | {lib} | {rs[0].budget:,} | {n_solved} | "
                f"{_fmt([r.solve_seconds for r in solved if r.solve_seconds is not None])} | "
                f"{_fmt([r.train_seconds for r in rs])} | "
                f"{statistics.median([r.solve_steps for r in solved]) if solved else '-'} | "
                f"{_fmt([r.final_mean for r in rs])} |"
            )
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--envs", default="CartPole-v1")
    ap.add_argument("--algos", default="ppo,dqn")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--section", default="Deep RL")
    ap.add_argument(
        "--full-budget",
        action="store_true",
        help="policylab trains its whole budget too, instead of stopping once solved",
    )
    args = ap.parse_args()
    torch.set_num_threads(1)
    results: list[Result] = []
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    for env_id in args.envs.split(","):
        for algo in args.algos.split(","):
            if not zoo_settings(algo, env_id):
                continue
            for seed in range(args.seeds):
                for runner in (run_policylab, run_sb3):
                    r = runner(algo, env_id, seed, args.full_budget)
                    results.append(r)
                    print(
                        f"{r.library:10s} {algo} {env_id} seed {seed}: "
                        f"train {r.train_seconds:.1f}s "
                        f"solved at {r.solve_steps} ({r.solve_seconds}) final {r.final_mean:.1f} "
                        f"evals {r.evals}",
                        flush=True,
                    )
    load1 = os.getloadavg()
    body = table(results, args.full_budget)
    speedups = []
    for algo, env_id in sorted({(r.algo, r.env_id) for r in results}):
        mine = [r for r in results if (r.algo, r.env_id) == (algo, env_id)]
        ours = [r for r in mine if r.library == "policylab"]
        sb3 = [r for r in mine if r.library == "SB3 (zoo)"]
        ours_solve = [r.solve_seconds for r in ours if r.solve_seconds]
        sb3_solve = [r.solve_seconds for r in sb3 if r.solve_seconds]
        sb3_budget = statistics.median([r.train_seconds for r in sb3]) if sb3 else None
        name = f"{algo.upper()} {env_id}"
        if ours_solve and sb3_budget and not args.full_budget:
            o = statistics.median(ours_solve)
            speedups.append(
                f"- {name}: SB3's median training time at its budget / policylab's median "
                f"time to solve = {sb3_budget:.1f} s / {o:.1f} s = {sb3_budget / o:.1f}x"
            )
        if ours and sb3_budget and args.full_budget:
            o = statistics.median([r.train_seconds for r in ours])
            speedups.append(
                f"- {name}: training time at the same budget, SB3 / policylab = "
                f"{sb3_budget:.1f} s / {o:.1f} s = {sb3_budget / o:.1f}x"
            )
        if ours_solve and sb3_solve:
            o, b = statistics.median(ours_solve), statistics.median(sb3_solve)
            speedups.append(
                f"- {name}: time to the first solved evaluation, SB3 / policylab = "
                f"{b:.1f} s / {o:.1f} s = {b / o:.1f}x"
            )
    evals = ", ".join(f"{k} every {v:,}" for k, v in EVAL_EVERY.items())
    speedup_text = "\n".join(speedups)
    notes = (
        f"\n\n{speedup_text}\n\n"
        f"Seeds 0-{args.seeds - 1}; evaluations ({evals} steps) on 100 greedy episodes, not "
        "counted in the times. Both libraries run with torch.set_num_threads(1), one after "
        "the other. Load average "
        f"{load0[0]:.1f} at the start and {load1[0]:.1f} at the end on 2 cores; whole "
        f"benchmark {time.perf_counter() - t0:.0f} s. policylab uses its `policylab train` "
        "defaults (`pl.deep.default_config`: the zoo settings plus the changes in "
        "`policylab.deep.zoo.TUNED`); SB3 uses the zoo settings as they are."
    )
    print(body + notes)
    if not args.no_write:
        from _report import write_section

        write_section(
            args.section,
            f"python benchmarks/bench_deep.py --seeds {args.seeds} --envs {args.envs} "
            f"--algos {args.algos}" + (" --full-budget" if args.full_budget else ""),
            body + notes,
        )


if __name__ == "__main__":
    main()
