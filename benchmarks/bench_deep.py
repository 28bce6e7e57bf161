"""Deep RL: policylab's PPO and DQN against Stable-Baselines3, measured like with like.

Two measurements, each with both libraries in the same run and torch limited to one
thread:

- ``--per-step``: env steps per second at identical settings (the rl-baselines3-zoo
  hyperparameters exactly, for both libraries: no policylab ``TUNED`` changes, the same
  activation, envs, rollout length, gradient steps, vanilla DQN), the same number of env
  steps, the two libraries' runs interleaved round by round so both see the same load;
  then one cProfile'd run of each, splitting the time between the env step, the policy's
  forward pass on the acting path, the update, and the rest.
- time to the first solved evaluation (the default), each library with its recommended
  settings (policylab: ``policylab train``'s defaults, the zoo plus ``TUNED``; SB3: the
  zoo's). Both follow one protocol: every ``eval_every`` steps the greedy policy plays
  100 episodes (not counted in the time) and training stops at the first evaluation
  whose mean reaches the threshold (CartPole-v1 475, Acrobot-v1 -100, LunarLander-v3
  200). ``--full-budget`` trains both to their whole budgets instead.

``--with-zoo-policylab`` adds policylab with the zoo's settings exactly to the
time-to-solve runs.

Usage: ``python benchmarks/bench_deep.py [--per-step] [--rounds 3] [--seeds 5]
[--envs CartPole-v1,Acrobot-v1] [--algos ppo,dqn] [--with-zoo-policylab]
[--full-budget] [--section NAME] [--no-write]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import torch

import policylab as pl
from policylab.deep.common.envs import is_atari_id
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
    solve_cpu_seconds: float | None = None  # the same in CPU time of the process
    solve_steps: int | None = None
    final_mean: float = float("nan")
    evals: list[tuple[int, float]] = field(default_factory=list)


class _Clock:
    """Training time, wall-clock and CPU, with evaluation pauses taken out."""

    def __init__(self) -> None:
        self.t0, self.c0 = time.perf_counter(), time.process_time()
        self.paused = self.paused_cpu = 0.0
        self._pause_start = (0.0, 0.0)

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0 - self.paused

    def elapsed_cpu(self) -> float:
        return time.process_time() - self.c0 - self.paused_cpu

    def start_pause(self) -> None:
        self._pause_start = (time.perf_counter(), time.process_time())

    def end_pause(self) -> None:
        self.paused += time.perf_counter() - self._pause_start[0]
        self.paused_cpu += time.process_time() - self._pause_start[1]


def _evaluate(act: Any, env_id: str, seed: int) -> float:
    return float(np.mean(run_episodes(act, env_id, 100, seed=10_000 + seed, n_envs=100)))


ZOO_LABEL = "policylab, zoo settings"


def run_policylab(
    algo: str, env_id: str, seed: int, full_budget: bool = False, tuned: bool = True
) -> Result:
    if tuned:
        fields, budget = pl.deep.default_config(algo, env_id)
    else:
        fields, budget = identical_settings(algo, env_id), zoo_settings(algo, env_id)["steps"]
    assert budget is not None
    res = Result("policylab" if tuned else ZOO_LABEL, algo, env_id, seed, budget)
    agent = pl.deep.ALGORITHMS[algo](env_id, seed=seed, **fields)
    every, thr = EVAL_EVERY[env_id], THRESHOLD[env_id]
    nxt = [every]
    clock = _Clock()

    def cb(a: pl.deep.Agent, _: dict[str, float]) -> bool | None:
        if a.num_timesteps < nxt[0]:
            return None
        nxt[0] += every
        t, c = clock.elapsed(), clock.elapsed_cpu()
        clock.start_pause()
        mean = _evaluate(lambda o: a.predict(o, deterministic=True), env_id, seed)
        clock.end_pause()
        res.evals.append((a.num_timesteps, mean))
        if mean >= thr and res.solve_steps is None:
            res.solve_seconds, res.solve_steps = t, a.num_timesteps
            res.solve_cpu_seconds = c
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
    from stable_baselines3.common.callbacks import BaseCallback

    budget = int(zoo_settings(algo, env_id)["steps"])
    res = Result("SB3", algo, env_id, seed, budget)
    model = _make_sb3(algo, env_id, seed, anneal_clip=True, per_step=False)
    venv = model.get_env()
    normalize = bool(zoo_settings(algo, env_id).get("normalize", False))
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
                t, c = clock.elapsed(), clock.elapsed_cpu()
                clock.start_pause()
                mean = _evaluate(act, env_id, seed)
                clock.end_pause()
                res.evals.append((self.num_timesteps, mean))
                if mean >= thr and res.solve_steps is None:
                    res.solve_seconds, res.solve_steps = t, self.num_timesteps
                    res.solve_cpu_seconds = c
                    return full_budget
            return True

    clock = _Clock()
    model.learn(budget, callback=Eval())
    res.train_seconds, res.steps = clock.elapsed(), model.num_timesteps
    res.final_mean = (
        res.evals[-1][1] if res.solve_steps and not full_budget else _evaluate(act, env_id, seed)
    )
    venv.close()
    return res


def save_result(path: str, r: Result) -> None:
    """Append one run to ``path`` as a JSON line (flushed, so a killed run keeps the others)."""
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(dataclasses.asdict(r)) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def load_results(path: str) -> list[Result]:
    """The runs saved by :func:`save_result`, in order."""
    out = []
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if line.strip():
                d = json.loads(line)
                d["evals"] = [tuple(e) for e in d["evals"]]
                out.append(Result(**d))
    return out


def _fmt(xs: list[float], digits: int = 1) -> str:
    if not xs:
        return "-"
    if len(xs) == 1:
        return f"{xs[0]:,.{digits}f}"
    return f"{statistics.median(xs):,.{digits}f} ({min(xs):,.{digits}f}-{max(xs):,.{digits}f})"


def table(results: list[Result], full_budget: bool = False) -> str:
    rows = [
        "| algorithm | env | library (settings) | budget (steps) | seeds solved "
        "| CPU time to first solve, s: median (range) | SB3 / policylab, median CPU time "
        "| wall-clock time, s: median (range) | steps to first solve: median (range) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    keys = sorted({(r.algo, r.env_id) for r in results}, key=lambda k: (k[1], k[0]))
    for algo, env_id in keys:
        by_lib = {
            lib: [r for r in results if (r.algo, r.env_id, r.library) == (algo, env_id, lib)]
            for lib in ("policylab", ZOO_LABEL, "SB3")
        }
        cpu = {
            lib: [r.solve_cpu_seconds for r in rs if r.solve_cpu_seconds is not None]
            for lib, rs in by_lib.items()
        }
        for lib, rs in by_lib.items():
            if not rs:
                continue
            ratio = (
                f"{statistics.median(cpu['SB3']) / statistics.median(cpu[lib]):.1f}x"
                if cpu[lib] and cpu["SB3"] and lib != "SB3"
                else ("" if lib == "SB3" else "-")
            )
            settings = {"policylab": "its defaults", ZOO_LABEL: "the zoo's, as SB3", "SB3": "zoo"}[
                lib
            ]
            solved = [r for r in rs if r.solve_steps is not None]
            steps = [float(r.solve_steps) for r in solved if r.solve_steps is not None]
            wall = [r.solve_seconds for r in solved if r.solve_seconds is not None]
            rows.append(
                f"| {algo.upper()} | {env_id} | {lib.split(',')[0]} ({settings}) | "
                f"{rs[0].budget:,} | {len(solved)}/{len(rs)} | {_fmt(cpu[lib])} | {ratio} | "
                f"{_fmt(wall)} | {_fmt(steps, 0)} |"
            )
    return "\n".join(rows)


# ---------------------------------------------------------------------------
# Per environment step at identical settings
# ---------------------------------------------------------------------------

PER_STEP_STEPS = {
    ("ppo", "CartPole-v1"): 20_480,
    ("dqn", "CartPole-v1"): 10_240,
    ("ppo", "Acrobot-v1"): 32_768,
    ("dqn", "Acrobot-v1"): 4_000,
    ("ppo", "LunarLander-v3"): 65_536,
    ("dqn", "LunarLander-v3"): 8_000,
    ("ppo", "ALE/Pong-v5"): 4_096,
    ("dqn", "ALE/Pong-v5"): 3_000,
}

# A short Atari run never reaches the zoo's 100k steps of DQN warm-up: both libraries
# start learning after 1,000 steps instead, with a buffer sized to the run.
PER_STEP_OVERRIDES = {("dqn", "atari"): {"learning_starts": 1_000, "buffer_size": 10_000}}


def _per_step_overrides(algo: str, env_id: str) -> dict[str, Any]:
    key = "atari" if is_atari_id(env_id) else env_id
    return dict(PER_STEP_OVERRIDES.get((algo, key), {}))


# Where each library spends a step, by the functions a profile charges it to:
# (file path fragment, function name). "act" is the env step plus the policy's forward
# pass on the acting path; "update" is the gradient-step phase; the rest is buffers,
# GAE, bookkeeping and logging.
_PHASES: dict[tuple[str, str], dict[str, list[tuple[str, str]]]] = {
    ("policylab", "ppo"): {
        "env": [],  # the outermost step of the agent's vector env, found at run time
        "forward": [("policylab/deep/ppo/agent.py", "_sample")],
        "update": [("policylab/deep/ppo/agent.py", "_update")],
    },
    ("policylab", "dqn"): {
        "env": [],
        "forward": [("policylab/deep/dqn/agent.py", "_epsilon_greedy")],
        "update": [("policylab/deep/dqn/agent.py", "_update")],
    },
    ("SB3", "ppo"): {
        "env": [("vec_env/dummy_vec_env.py", "step_wait")],
        "forward": [("stable_baselines3/common/policies.py", "forward")],
        "update": [("stable_baselines3/ppo/ppo.py", "train")],
    },
    ("SB3", "dqn"): {
        "env": [("vec_env/dummy_vec_env.py", "step_wait")],
        "forward": [("stable_baselines3/common/policies.py", "predict")],
        "update": [("stable_baselines3/dqn/dqn.py", "train")],
    },
}


def identical_settings(algo: str, env_id: str) -> dict[str, Any]:
    """policylab config fields equal to what SB3 runs with the zoo's settings.

    The zoo's settings without policylab's ``TUNED`` changes, plus SB3's own defaults
    where policylab's differ: vanilla (not Double) DQN, and the activations of SB3's
    MlpPolicy (tanh for PPO, ReLU for DQN, which are also policylab's defaults).
    """
    fields, _ = pl.deep.default_config(algo, env_id, tuned=False)
    fields["activation"] = "tanh" if algo == "ppo" else "relu"
    if algo == "dqn":
        fields["double_q"] = False
    return fields


def _make_policylab(algo: str, env_id: str, seed: int, per_step: bool = True) -> Any:
    fields = identical_settings(algo, env_id)
    if per_step:
        fields.update(_per_step_overrides(algo, env_id))
    return pl.deep.ALGORITHMS[algo](env_id, seed=seed, **fields)


def _make_sb3(
    algo: str, env_id: str, seed: int, anneal_clip: bool = False, per_step: bool = True
) -> Any:
    """SB3's agent with the zoo's settings; ``anneal_clip`` also anneals PPO's clip range
    where the zoo anneals the learning rate (the zoo's recommended ``lin_`` schedules;
    policylab anneals only the learning rate, so the per-step comparison leaves it).
    An Atari game gets policylab's own env (``pl.deep.make_env``: the same no-op starts,
    frame skip, 84x84 grey frames and stack of 4) and SB3's ``CnnPolicy``."""
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    z = zoo_settings(algo, env_id)
    if per_step:
        z.update(_per_step_overrides(algo, env_id))
    z.pop("steps")
    normalize = z.pop("normalize", False)
    n_envs = int(z.pop("n_envs", 1))
    hidden = z.pop("hidden", None)
    anneal = z.pop("anneal_lr", False)
    atari = is_atari_id(env_id)
    venv = make_vec_env(
        partial(pl.deep.make_env, env_id) if atari else env_id, n_envs=n_envs, seed=seed
    )
    policy = "CnnPolicy" if atari else "MlpPolicy"
    if normalize:
        venv = VecNormalize(venv, gamma=z.get("gamma", 0.99))
    kwargs: dict[str, Any] = dict(z)
    if algo == "ppo":
        lr = kwargs.pop("learning_rate", 3e-4)
        kwargs["learning_rate"] = _linear(lr) if anneal else lr
        if anneal and anneal_clip:
            kwargs["clip_range"] = _linear(kwargs.get("clip_range", 0.2))
        return PPO(policy, venv, seed=seed, device="cpu", **kwargs)
    if hidden is not None:
        kwargs["policy_kwargs"] = {"net_arch": list(hidden)}
    return DQN(policy, venv, seed=seed, device="cpu", **kwargs)


@dataclass
class StepResult:
    library: str
    algo: str
    env_id: str
    steps_per_second: list[float] = field(default_factory=list)
    steps_per_cpu_second: list[float] = field(default_factory=list)
    phases: dict[str, float] = field(default_factory=dict)  # fractions of the profiled time


def _timed_learn(
    library: str, algo: str, env_id: str, steps: int, seed: int
) -> tuple[float, float]:
    """Env steps per wall-clock second and per CPU second of one unprofiled run."""
    model = (_make_policylab if library == "policylab" else _make_sb3)(algo, env_id, seed)
    t0, c0 = time.perf_counter(), time.process_time()
    model.learn(steps)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return model.num_timesteps / wall, model.num_timesteps / cpu


def _profiled_phases(
    library: str, algo: str, env_id: str, steps: int, seed: int
) -> dict[str, float]:
    """Fractions of a cProfile'd training run spent acting, updating, and on the rest."""
    import cProfile
    import pstats

    prof = cProfile.Profile()
    spec = {k: list(v) for k, v in _PHASES[(library, algo)].items()}
    if library == "policylab":
        agent = _make_policylab(algo, env_id, seed)
        step = type(agent.envs).step
        spec["env"].append((step.__code__.co_filename, step.__code__.co_name))
        prof.enable()
        agent.learn(steps)
    else:
        model = _make_sb3(algo, env_id, seed)
        prof.enable()
        model.learn(steps)
    prof.disable()
    stats: Any = pstats.Stats(prof).stats  # {(file, line, name): (cc, nc, tt, ct, callers)}
    total = sum(v[2] for v in stats.values())

    def cum(patterns: list[tuple[str, str]]) -> float:
        out = 0.0
        for (file, _, name), (_, _, _, ct, callers) in stats.items():
            if not any(frag in file.replace("\\", "/") and name == fn for frag, fn in patterns):
                continue
            # count only calls from outside the matched set (no double counting of
            # wrappers that call each other, e.g. a vector env's step calling an env's)
            inner = sum(
                c[3]
                for (cf, _, cn), c in callers.items()
                if any(frag in cf.replace("\\", "/") and cn == fn for frag, fn in patterns)
            )
            out += ct - inner
        return out

    env_t, fwd_t, upd_t = cum(spec["env"]), cum(spec["forward"]), cum(spec["update"])
    return {
        "env step": env_t / total,
        "policy forward": fwd_t / total,
        "update": upd_t / total,
        "rest": max(0.0, 1.0 - (env_t + fwd_t + upd_t) / total),
    }


def per_step(envs: list[str], algos: list[str], rounds: int) -> list[StepResult]:
    """Both libraries at identical settings, interleaved run by run, one torch thread."""
    results: list[StepResult] = []
    for env_id in envs:
        for algo in algos:
            key = (algo, env_id)
            if key not in PER_STEP_STEPS or not zoo_settings(algo, env_id):
                continue
            steps = PER_STEP_STEPS[key]
            pair = [StepResult(lib, algo, env_id) for lib in ("policylab", "SB3")]
            for r in range(rounds):
                for res in pair if r % 2 == 0 else pair[::-1]:
                    sps, cps = _timed_learn(res.library, algo, env_id, steps, seed=r)
                    res.steps_per_second.append(sps)
                    res.steps_per_cpu_second.append(cps)
                    print(f"{res.library:9s} {algo} {env_id} round {r}: {sps:,.0f} steps/s, "
                          f"{cps:,.0f} steps/CPU-s", flush=True)  # fmt: skip
            for res in pair:
                res.phases = _profiled_phases(res.library, algo, env_id, steps, seed=0)
                print(f"{res.library:9s} {algo} {env_id} profile: {res.phases}", flush=True)
            results.extend(pair)
    return results


def _mm_seconds(m: int, k: int, n: int, repeats: int = 200) -> float:
    """CPU seconds of one (m, k) @ (k, n) float32 product (the fastest of 5 batches)."""
    a, b = torch.randn(m, k), torch.randn(k, n)
    for _ in range(20):
        torch.mm(a, b)
    best = float("inf")
    for _ in range(5):
        c0 = time.process_time()
        for _ in range(repeats):
            torch.mm(a, b)
        best = min(best, (time.process_time() - c0) / repeats)
    return best


def _mlp_mm_seconds(dims: list[int], batch: int, backward: bool) -> float:
    """The matrix products of an MLP's forward pass (and its backward pass) on a batch."""
    t = 0.0
    for i, (d_in, d_out) in enumerate(itertools.pairwise(dims)):
        t += _mm_seconds(batch, d_in, d_out)  # forward
        if backward:
            t += min(_mm_seconds(d_out, batch, d_in), _mm_seconds(d_in, batch, d_out))  # dW
            if i > 0:
                t += _mm_seconds(batch, d_out, d_in)  # dL/d(input)
    return t


def matmul_bound(algo: str, env_id: str) -> float:
    """Env steps per CPU-second if a step cost only the matrix products it needs.

    The products of the acting forward passes and of the gradient steps (forward and
    backward through each MLP; DQN's target network forward), at the zoo's settings:
    no implementation of the same arithmetic runs faster on this CPU with one thread.
    """
    f = identical_settings(algo, env_id)
    space = pl.deep.make_vec_env(env_id, 1)
    obs = int(np.prod(space.single_observation_space.shape))
    n_act = int(space.single_action_space.n)
    hidden = list(f.get("hidden", (64, 64)))
    n_envs = int(f.get("n_envs", 1))
    if algo == "ppo":
        rollout = int(f["n_steps"]) * n_envs
        batch = int(f.get("batch_size", 64))
        per_grad = _mlp_mm_seconds([obs, *hidden, n_act], batch, True) + _mlp_mm_seconds(
            [obs, *hidden, 1], batch, True
        )
        grads_per_step = int(f.get("n_epochs", 10)) * max(1, round(rollout / batch)) / rollout
        act = _mlp_mm_seconds([obs, *hidden, n_act], n_envs, False) + _mlp_mm_seconds(
            [obs, *hidden, 1], n_envs, False
        )
    else:
        batch = int(f.get("batch_size", 32))
        dims = [obs, *hidden, n_act]
        per_grad = _mlp_mm_seconds(dims, batch, True) + _mlp_mm_seconds(dims, batch, False)
        grads_per_step = int(f.get("gradient_steps", 1)) / int(f.get("train_freq", 4))
        act = _mlp_mm_seconds(dims, n_envs, False)
    return 1.0 / (per_grad * grads_per_step + act / n_envs)


def per_step_table(results: list[StepResult]) -> str:
    rows = [
        "| algorithm | env | library | env steps/s: median (range) | policylab / SB3 "
        "| env steps per CPU-second | policylab / SB3 (CPU) "
        "| env step | policy forward | update | rest |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for i in range(0, len(results), 2):
        ours, sb3 = results[i], results[i + 1]
        med = statistics.median
        ratio = med(ours.steps_per_second) / med(sb3.steps_per_second)
        cpu_ratio = med(ours.steps_per_cpu_second) / med(sb3.steps_per_cpu_second)
        for res in (ours, sb3):
            sps, cps = res.steps_per_second, res.steps_per_cpu_second
            p = res.phases
            rows.append(
                f"| {res.algo.upper()} | {res.env_id} | {res.library} | "
                f"{med(sps):,.0f} ({min(sps):,.0f}-{max(sps):,.0f}) | "
                f"{f'{ratio:.2f}x' if res is ours else ''} | "
                f"{med(cps):,.0f} ({min(cps):,.0f}-{max(cps):,.0f}) | "
                f"{f'{cpu_ratio:.2f}x' if res is ours else ''} | "
                + " | ".join(f"{100 * p[k]:.0f}%" for k in ("env step", "policy forward",
                                                            "update", "rest"))
                + " |"
            )  # fmt: skip
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(
        description="policylab's PPO and DQN against Stable-Baselines3: env steps per "
        "CPU-second at identical settings (--per-step), or CPU time to the first solved "
        "evaluation with each library's recommended settings (the default).",
    )
    ap.add_argument(
        "--seeds",
        type=int,
        default=5,
        help="time to solve: seeds per library, algorithm and env (FIRST .. FIRST+SEEDS-1, "
        "FIRST from --first-seed; default 5)",
    )
    ap.add_argument(
        "--first-seed",
        type=int,
        default=0,
        help="time to solve: the first seed (default 0), so that seeds can be split across "
        "processes, e.g. one per core, each with --no-write",
    )
    ap.add_argument(
        "--envs",
        default="CartPole-v1",
        help="comma-separated Gymnasium ids: CartPole-v1, Acrobot-v1, LunarLander-v3, "
        "ALE/Pong-v5 (--per-step only) (default CartPole-v1)",
    )
    ap.add_argument(
        "--algos", default="ppo,dqn", help="comma-separated algorithms: ppo, dqn (default both)"
    )
    ap.add_argument(
        "--no-write",
        action="store_true",
        help="print the table only; by default it also replaces its section of BENCHMARKS.md",
    )
    ap.add_argument(
        "--section",
        default=None,
        help="the BENCHMARKS.md section to write (default: 'Deep RL: per step at identical "
        "settings' with --per-step, else 'Deep RL: time to first solve')",
    )
    ap.add_argument(
        "--per-step",
        action="store_true",
        help="env steps per second at identical settings, with a profile of each library",
    )
    ap.add_argument(
        "--with-zoo-policylab",
        action="store_true",
        help="time to solve: also run policylab with the zoo's settings exactly",
    )
    ap.add_argument(
        "--rounds",
        type=int,
        default=3,
        help="--per-step: timed runs per library, the libraries alternating (default 3)",
    )
    ap.add_argument(
        "--matmul-bound",
        action="store_true",
        help="print the steps per CPU-second the matrix products alone would allow, and stop",
    )
    ap.add_argument(
        "--results",
        default=None,
        metavar="FILE",
        help="time to solve: also append each run to FILE as a JSON line, so that runs "
        "split across processes can be put in one table with --from-results",
    )
    ap.add_argument(
        "--from-results",
        default=None,
        metavar="FILES",
        help="time to solve: run nothing; build the table (and its section, unless "
        "--no-write) from comma-separated files written by --results; the rows and the "
        "seeds in the notes are those of the saved runs",
    )
    ap.add_argument(
        "--full-budget",
        action="store_true",
        help="train both libraries to their whole budgets instead of stopping once solved",
    )
    args = ap.parse_args()
    torch.set_num_threads(1)
    envs, algos = args.envs.split(","), args.algos.split(",")
    if args.matmul_bound:
        print("| algorithm | env | env steps per CPU-second, matrix products alone |")
        print("|---|---|---|")
        for env_id in envs:
            for algo in algos:
                print(f"| {algo.upper()} | {env_id} | {matmul_bound(algo, env_id):,.0f} |")
        print(f"load average {os.getloadavg()[0]:.1f} on 2 cores")
        return
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    if args.per_step:
        section = args.section or "Deep RL: per step at identical settings"
        command = (
            f"python benchmarks/bench_deep.py --per-step --rounds {args.rounds} "
            f"--envs {args.envs} --algos {args.algos}"
        )
        body = per_step_table(per_step(envs, algos, args.rounds))
        budgets = ", ".join(
            f"{a.upper()} {e} {n:,}"
            for (a, e), n in PER_STEP_STEPS.items()
            if a in algos and e in envs
        )
        notes = (
            "Both libraries with the rl-baselines3-zoo hyperparameters exactly (policylab "
            "without its `TUNED` changes: `benchmarks/bench_deep.py:identical_settings`), "
            "torch.set_num_threads(1), the same number of env steps "
            f"({budgets}), "
            f"{args.rounds} timed runs each, the two libraries alternating run by run. "
            "Steps per CPU-second divide by the process's CPU time (`time.process_time`), "
            "which the other jobs on the machine disturb less than the wall clock. "
            "The split (env step, policy forward on the acting path, update, rest) is the "
            "share of one further cProfile'd run of each (cProfile adds a per-call cost, "
            "so it overstates Python-heavy parts). The env step is each library's own: "
            "policylab steps CartPole-v1 with Gymnasium's CartPole (NumPy-vectorised for "
            "several envs) and Acrobot-v1 with its own Acrobot (Gymnasium's dynamics bit "
            "for bit: NumPy-vectorised for several envs, on Python floats for one), SB3 "
            "both with a DummyVecEnv of single envs; LunarLander-v3 is a loop over single "
            "envs in both."
        )  # fmt: skip
    else:
        section = args.section or "Deep RL: time to first solve"
        command = (
            f"python benchmarks/bench_deep.py --seeds {args.seeds} --envs {args.envs} "
            f"--algos {args.algos}"
            + (f" --first-seed {args.first_seed}" if args.first_seed else "")
            + (" --full-budget" if args.full_budget else "")
            + (" --with-zoo-policylab" if args.with_zoo_policylab else "")
        )
        results: list[Result] = []
        if args.from_results:
            results = [r for f in args.from_results.split(",") for r in load_results(f)]
        for env_id in [] if args.from_results else envs:
            for algo in algos:
                if not zoo_settings(algo, env_id):
                    continue
                for seed in range(args.first_seed, args.first_seed + args.seeds):
                    variants = [True, False] if args.with_zoo_policylab else [True]
                    runs: list[Callable[[], Result]] = [
                        partial(run_policylab, algo, env_id, seed, args.full_budget, tuned)
                        for tuned in variants
                    ]
                    runs.append(partial(run_sb3, algo, env_id, seed, args.full_budget))
                    for runner in runs:
                        r = runner()
                        results.append(r)
                        if args.results:
                            save_result(args.results, r)
                        print(
                            f"{r.library:10s} {algo} {env_id} seed {seed}: "
                            f"train {r.train_seconds:.1f}s solved at {r.solve_steps} "
                            f"({r.solve_seconds} s wall, {r.solve_cpu_seconds} s CPU) "
                            f"final {r.final_mean:.1f} evals {r.evals}",
                            flush=True,
                        )
        body = table(results, args.full_budget)
        evals = ", ".join(f"{k} every {v:,}" for k, v in EVAL_EVERY.items())
        seeds = sorted({r.seed for r in results}) or [args.first_seed]
        notes = (
            f"Seeds {seeds[0]}-{seeds[-1]}, each library with "
            "its recommended settings "
            "(policylab: `policylab train`'s defaults, `pl.deep.default_config`, the zoo "
            "settings plus `policylab.deep.zoo.TUNED`, which changes nothing for PPO; SB3: "
            "the zoo settings). Times are of training only, in CPU seconds of the process "
            "(one torch thread; less disturbed by the machine's other jobs than the wall "
            "clock, which is given too). One "
            f"protocol for both: evaluations ({evals} steps) of 100 greedy episodes, not "
            "counted in the times; training stops at the first evaluation that reaches "
            "the threshold (CartPole-v1 475, Acrobot-v1 -100, LunarLander-v3 200). Both "
            "libraries with torch.set_num_threads(1), seed by seed one after the other. "
            "policylab checks for an evaluation after each iteration, so its step counts "
            "are those of the first iteration past each multiple of the interval."
            + (
                " The row 'the zoo's, as SB3' is policylab with the zoo's settings "
                "exactly, as in the per-step table."
                if args.with_zoo_policylab
                else ""
            )
        )
    load1 = os.getloadavg()
    from _report import load_note, write_section

    if args.from_results:
        notes += f" Built from saved runs ({args.from_results}); the runs' load is in their logs."
        command += f" --from-results {args.from_results}"
    else:
        notes += (
            f" {load_note(load0[0], load1[0])} Whole benchmark {time.perf_counter() - t0:.0f} s."
        )
    print(body + "\n\n" + notes)
    if args.section:
        command += f' --section "{args.section}"'
    if not args.no_write:
        write_section(section, command, body + "\n\n" + notes)


if __name__ == "__main__":
    main()
