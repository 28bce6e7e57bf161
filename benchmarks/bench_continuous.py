"""SAC and TD3 against Stable-Baselines3: env steps per second on HalfCheetah-v5, Pendulum-v1.

Speed: both libraries train the same number of steps with the same hyperparameters
(SB3's defaults: batch 256, buffer, tau 0.005, one gradient step per env step after
``--learning-starts`` random steps; SAC 256x256 networks with a learned temperature,
TD3 400x300 networks with N(0, 0.1^2) exploration noise), on one torch thread, one
library after the other and alternating their order over ``--repeats`` rounds, so
that a loaded machine slows both alike. Reported: wall-clock env steps per second and
CPU milliseconds per gradient update (process time, which counts only the CPU this
process got).

Quality (``--pendulum``): policylab's SAC and TD3 with the zoo's Pendulum-v1 settings
for 20k steps, on ``--seeds`` seeds, evaluated greedily on ``--episodes`` episodes (750,
the zoo's protocol of 150,000 evaluation steps); ``--sb3`` trains SB3 alongside.
``--quality ENV_ID --budget N`` does the same on a MuJoCo walker with the zoo's settings
for it (10 evaluation episodes by default). ``--summarize FILE`` tabulates such runs: the
mean over seeds with its bootstrap interval, and where both libraries ran, policylab
against SB3 (difference of means, probability of improvement, exact permutation tests).
``--fill FILE`` runs what such a table still lacks: each (env, algorithm, library, seed)
run missing from FILE, one process pinned to each core, appending as each finishes.

    python benchmarks/bench_continuous.py                  # the speed table
    python benchmarks/bench_continuous.py --pendulum       # the Pendulum-v1 table
    python benchmarks/bench_continuous.py --quality Hopper-v5 --budget 200000 --sb3
    python benchmarks/bench_continuous.py --fill benchmarks/results/quality-200k.jsonl
    python benchmarks/bench_continuous.py --per-update 60  # single updates, alternating
    python benchmarks/bench_continuous.py --walker runs/walker-walking  # how a walker walks

``--walker RUN_DIR`` reads a run of ``policylab train ... --reward walking``: it plays
``--episodes`` greedy episodes of its policy on the plain env and prints the forward
velocity (the root's x displacement over the episode's duration, and the mean of
``info["x_velocity"]``), the episode lengths and both returns, and draws the run's
learning curve (``progress.csv``: the return of the recent training episodes under the
reward it trained on) with policylab's plotting into ``RUN_DIR/learning_curve.png``
(``--figure`` elsewhere).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import machine, processor, write_section

NETS = {"sac": (256, 256), "td3": (400, 300)}


@dataclass
class Timing:
    lib: str
    algo: str
    seconds: float
    cpu_seconds: float
    steps: int
    updates: int


def _common(args: argparse.Namespace) -> dict[str, object]:
    return dict(
        learning_starts=args.learning_starts,
        buffer_size=args.buffer_size,
        batch_size=256,
        tau=0.005,
        gamma=0.99,
        train_freq=1,
        gradient_steps=1,
    )


def time_policylab(algo: str, args: argparse.Namespace, seed: int) -> Timing:
    import policylab as pl

    cls = pl.deep.ALGORITHMS[algo]
    extra: dict[str, object] = {"action_noise": 0.1} if algo == "td3" else {}
    agent = cls(args.env, seed=seed, hidden=NETS[algo], **_common(args), **extra)
    t, c = time.perf_counter(), time.process_time()
    agent.learn(args.steps)
    return Timing(
        "policylab", algo, time.perf_counter() - t, time.process_time() - c,
        agent.num_timesteps, agent.n_updates,
    )  # fmt: skip


def time_sb3(algo: str, args: argparse.Namespace, seed: int) -> Timing:
    import gymnasium as gym
    from stable_baselines3 import SAC, TD3
    from stable_baselines3.common.noise import NormalActionNoise

    env = gym.make(args.env)
    kw: dict[str, object] = dict(
        seed=seed, device="cpu", policy_kwargs=dict(net_arch=list(NETS[algo])), **_common(args)
    )
    if algo == "td3":
        m = env.action_space.shape[0]
        model = TD3(
            "MlpPolicy", env, action_noise=NormalActionNoise(np.zeros(m), 0.1 * np.ones(m)), **kw
        )
    else:
        model = SAC("MlpPolicy", env, **kw)
    t, c = time.perf_counter(), time.process_time()
    model.learn(args.steps)
    return Timing(
        "SB3", algo, time.perf_counter() - t, time.process_time() - c,
        int(model.num_timesteps), int(model._n_updates),
    )  # fmt: skip


def _load() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return f"load average {os.getloadavg()}"


def speed(args: argparse.Namespace) -> None:
    import torch

    torch.set_num_threads(1)
    loads = [_load()]
    results: list[Timing] = []
    for algo in args.algos:
        for r in range(args.repeats):
            order = [time_policylab, time_sb3] if r % 2 == 0 else [time_sb3, time_policylab]
            for fn in order:
                res = fn(algo, args, r)
                results.append(res)
                print(
                    f"{res.lib:9s} {algo}: {res.steps} steps, {res.updates} updates, "
                    f"{res.seconds:.1f} s, {res.steps / res.seconds:.0f} steps/s, "
                    f"{1000 * res.cpu_seconds / max(res.updates, 1):.2f} CPU ms/update",
                    flush=True,
                )
    loads.append(_load())
    rows = [
        "| algorithm | library | runs | updates | wall-clock s (median) | env steps/s "
        "| CPU ms per update | policylab / SB3 steps/s |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for algo in args.algos:
        med: dict[str, float] = {}
        for lib in ("SB3", "policylab"):
            rs = [x for x in results if x.algo == algo and x.lib == lib]
            sec = float(np.median([x.seconds for x in rs]))
            cpu = float(np.median([1000 * x.cpu_seconds / max(x.updates, 1) for x in rs]))
            med[lib] = rs[0].steps / sec
            ratio = f"{med['policylab'] / med['SB3']:.2f}x" if lib == "policylab" else ""
            rows.append(
                f"| {algo.upper()} | {lib} | {len(rs)} | {rs[0].updates:,} | {sec:.1f} "
                f"| {med[lib]:.0f} | {cpu:.2f} | {ratio} |"
            )
    body = (
        f"{args.env}, {args.steps:,} env steps with {args.learning_starts:,} random steps first "
        f"(one gradient update per later step), batch 256, one torch thread, both libraries "
        f"in the same run, alternating. Load before and after (2 cores shared with other "
        f"developers' jobs, so absolute times are inflated and noisy; the ratio is the "
        f"measurement):\n\n    {loads[0]}\n    {loads[1]}\n\n" + "\n".join(rows)
    )
    print(body)
    if args.write:
        write_section(
            "Deep RL: SAC and TD3 speed on HalfCheetah-v5",
            f"python benchmarks/bench_continuous.py --steps {args.steps} --learning-starts "
            f"{args.learning_starts} --repeats {args.repeats}",
            body,
        )


def _floor(algo: str, obs_dim: int, m: int, hidden: tuple[int, int], b: int) -> object:
    """The matrix products of one update of ``algo``, bare (random operands, no autograd).

    SAC: the policy at S and S' (2B rows) and its backward at S; the target critics at
    S'; the critics at (S, A), forward and backward with weight gradients; the critics
    at (S, a ~ pi) and their backward to the action. TD3: the target actor at S', the
    target critics, the critics forward and backward, and, every second update (half
    of it is counted: run it with weight 1/2), the actor at S, Q_1 at (S, mu(S)) and
    both backward. The two critics are one batched product per layer, as both
    libraries' arithmetic allows; the one-output layer and element-wise work are left
    out, so this is a lower bound for any implementation of the same update.
    """
    import torch

    h1, h2 = hidden
    d = obs_dim + m + 1
    r = torch.randn
    x2, xb = r(2 * b, obs_dim), r(b, obs_dim)
    w1, w2, w3 = r(h1, obs_dim), r(h2, h1), r((2 if algo == "sac" else 1) * m, h2)
    h1b2, h2b = r(2 * b, h1), r(b, h2)
    g3, g2 = r(b, w3.shape[0]), r(b, h2)
    xc, w_in, hk, wk, bk, gk, wa = (
        r(b, d),
        r(2, d, h1),
        r(2, b, h1),
        r(2, h1, h2),
        r(2, 1, h2),
        r(2, b, h2),
        r(2, m, h1),
    )
    gk1 = r(2, b, h1)

    def critic(k: int = 2) -> None:  # forward of k critics
        torch.bmm(xc.unsqueeze(0).expand(k, -1, -1), w_in[:k])
        torch.baddbmm(bk[:k], hk[:k], wk[:k])

    def actor(rows: int) -> None:
        (
            torch.mm(x2[:rows], w1.t()),
            torch.mm(h1b2[:rows], w2.t()),
            torch.mm(h1b2[:rows, :h2], w3.t()),
        )

    def actor_backward() -> None:
        torch.mm(g3.t(), h2b), torch.mm(g3, w3), torch.mm(g2.t(), h1b2[:b]), torch.mm(g2, w2)
        torch.mm(xb.t(), h1b2[:b])

    def critic_backward(k: int = 2, weights: bool = True) -> None:
        if weights:
            torch.bmm(hk.transpose(1, 2), gk), torch.bmm(xc.t().unsqueeze(0).expand(2, -1, -1), gk1)
        torch.bmm(gk[:k], wk[:k].transpose(1, 2)), torch.bmm(gk1[:k], wa[:k].transpose(1, 2))

    if algo == "sac":

        def every() -> None:
            actor(2 * b), actor_backward()
            critic(), critic(), critic_backward(), critic(), critic_backward(weights=False)

        return every, None

    def every_td3() -> None:
        actor(b), critic(), critic(), critic_backward()

    def delayed() -> None:
        actor(b), critic(1), critic_backward(1, weights=False), actor_backward()

    return every_td3, delayed


def _flops(fn: object) -> int:
    """Floating-point operations of the matrix products ``fn`` runs (torch's flop counter)."""
    from torch.utils.flop_counter import FlopCounterMode

    with FlopCounterMode(display=False) as counter:
        fn()  # type: ignore[operator]
    return int(counter.get_total_flops())


def _hot_rate(hidden: tuple[int, int], b: int) -> float:
    """GFLOP/s of the update's largest product, (B, H_1) (H_1, H_2), with hot operands.

    The product repeated on the same operands, so they stay in the core's cache: the
    best rate this CPU reaches on the update's typical shape, one thread.
    """
    import torch

    x, w = torch.randn(b, hidden[0]), torch.randn(hidden[0], hidden[1])
    ts = []
    for i in range(60):
        t = time.thread_time()
        torch.mm(x, w)
        if i >= 10:
            ts.append(time.thread_time() - t)
    return 2 * b * hidden[0] * hidden[1] / float(np.percentile(ts, 25)) / 1e9


def per_update(args: argparse.Namespace) -> None:
    """CPU ms of single updates of both libraries, alternating in one process (p25)."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC, TD3
    from stable_baselines3.common.noise import NormalActionNoise

    import policylab as pl

    torch.set_num_threads(1)
    print(machine())
    print(_load())
    for algo in args.algos:
        kw = dict(_common(args), learning_starts=300, buffer_size=10_000)
        agent = pl.deep.ALGORITHMS[algo](args.env, seed=0, hidden=NETS[algo], **kw)
        agent.learn(400)
        env = gym.make(args.env)
        sb_kw: dict[str, object] = dict(
            seed=0, device="cpu", policy_kwargs=dict(net_arch=list(NETS[algo])), **kw
        )
        if algo == "sac":
            model = SAC("MlpPolicy", env, **sb_kw)
        else:
            m = env.action_space.shape[0]
            noise = NormalActionNoise(np.zeros(m), 0.1 * np.ones(m))
            model = TD3("MlpPolicy", env, action_noise=noise, **sb_kw)
        model.learn(400)

        def ours(agent: object = agent) -> None:
            stats = agent._train_step(agent.replay.sample(256))  # type: ignore[attr-defined]
            torch.stack(list(stats.values())).tolist()

        def sb3(model: object = model) -> None:
            model.train(gradient_steps=1, batch_size=256)  # type: ignore[attr-defined]

        every, delayed = _floor(  # type: ignore[misc]
            algo, agent.obs_dim, agent.action_dim, NETS[algo], 256
        )
        fns = [("policylab", ours), ("SB3", sb3), ("floor", every)]
        if delayed is not None:
            fns.append(("floor, delayed part", delayed))
        times: dict[str, list[float]] = {lib: [] for lib, _ in fns}
        for i in range(args.per_update + 10):
            for lib, fn in fns[:: 1 if i % 2 == 0 else -1]:
                t = time.process_time()
                fn()
                if i >= 10:  # the first ten of each warm up
                    times[lib].append(time.process_time() - t)
        ms = {lib: 1000 * float(np.percentile(ts, 25)) for lib, ts in times.items()}
        floor = ms["floor"] + ms.get("floor, delayed part", 0.0) / 2  # TD3: every 2nd update
        gflop = (_flops(every) + (_flops(delayed) / 2 if delayed is not None else 0)) / 1e9
        rate = _hot_rate(NETS[algo], 256)
        print(
            f"{algo.upper()}: policylab {ms['policylab']:.2f} ms, SB3 {ms['SB3']:.2f} ms CPU per "
            f"update (25th percentile of {args.per_update} alternating updates each), "
            f"SB3 / policylab {ms['SB3'] / ms['policylab']:.2f}x; the update's matrix products "
            f"alone (the floor) {floor:.2f} ms: policylab at {ms['policylab'] / floor:.2f}x "
            f"the floor, SB3 at {ms['SB3'] / floor:.2f}x. Those products count {gflop:.3f} "
            f"GFLOP an update; at {rate:.0f} GFLOP/s (one {NETS[algo][0]}x{NETS[algo][1]} "
            f"product with its operands in cache) they would take {gflop / rate * 1e3:.2f} ms",
            flush=True,
        )
    print(_load())


def _sb3_model(algo: str, env_id: str, seed: int, steps: int, callback: object = None) -> object:
    """SB3's model trained with the zoo's entry for ``env_id`` (the same as policylab's).

    Pendulum-v1: the zoo's own entry; a MuJoCo walker: the zoo's "mujoco-defaults"
    (SB3's defaults, 10,000 random steps first; TD3 with N(0, 0.1^2) action noise).
    ``callback``: an SB3 callback for ``learn``.
    """
    import gymnasium as gym
    from stable_baselines3 import SAC, TD3
    from stable_baselines3.common.noise import NormalActionNoise

    m = int(np.prod(gym.make(env_id).action_space.shape))  # type: ignore[arg-type]
    noise = NormalActionNoise(np.zeros(m), 0.1 * np.ones(m))
    kw: dict[str, object] = dict(seed=seed, device="cpu")
    if env_id == "Pendulum-v1":
        if algo == "sac":
            model: object = SAC("MlpPolicy", env_id, learning_rate=1e-3, **kw)
        else:
            model = TD3(
                "MlpPolicy", env_id, gamma=0.98, buffer_size=200_000, learning_starts=10_000,
                action_noise=noise, learning_rate=1e-3, policy_kwargs=dict(net_arch=[400, 300]),
                **kw,
            )  # fmt: skip
    elif algo == "sac":
        model = SAC("MlpPolicy", env_id, learning_starts=10_000, **kw)
    else:
        model = TD3(
            "MlpPolicy", env_id, learning_starts=10_000, action_noise=noise,
            learning_rate=1e-3, policy_kwargs=dict(net_arch=[400, 300]), **kw,
        )  # fmt: skip
    model.learn(steps, callback=callback)  # type: ignore[attr-defined]
    return model


class _SB3Predictor:
    def __init__(self, model: object) -> None:
        self.model = model

    def predict(self, obs: object, deterministic: bool = True) -> object:
        return self.model.predict(obs, deterministic=deterministic)[0]  # type: ignore[attr-defined]


def _commit() -> str:
    """The checkout's commit (short hash, '+' if it has uncommitted changes), or '?'."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        return "?"
    return (head or "?") + ("+" if dirty else "")


def quality(args: argparse.Namespace) -> None:
    """Train with the zoo's settings for ``args.quality``, then evaluate the greedy policy."""
    import torch

    import policylab as pl

    torch.set_num_threads(1)
    env_id = args.quality
    loads = [_load()]
    published = {"sac": -157.0, "td3": -152.0} if env_id == "Pendulum-v1" else {}
    libs = args.libs or (["policylab", "SB3"] if args.sb3 else ["policylab"])
    rows = [
        f"| algorithm | library | seed | mean return, {args.episodes} greedy episodes "
        "| SB3 zoo's published | wall-clock s |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for algo in args.algos:
        fields, zoo_steps = pl.deep.default_config(algo, env_id)
        steps = int(args.budget or zoo_steps or 20_000)
        for seed in args.seed_list or range(args.seeds):
            for lib in libs:
                t = time.perf_counter()
                if lib == "policylab":
                    agent: object = pl.deep.ALGORITHMS[algo](env_id, seed=seed, **fields)
                    agent.learn(steps)  # type: ignore[attr-defined]
                else:
                    agent = _SB3Predictor(_sb3_model(algo, env_id, seed, steps))
                sec = time.perf_counter() - t
                if args.save_dir:  # the final policy, for probes after the run
                    stem = Path(args.save_dir) / f"{env_id}-{algo}-{lib}-{seed}"
                    stem.parent.mkdir(parents=True, exist_ok=True)
                    if lib == "policylab":
                        agent.save(stem.with_suffix(".pt"))  # type: ignore[attr-defined]
                    else:
                        agent.model.save(str(stem.with_suffix(".zip")))  # type: ignore[attr-defined]
                episodes, eval_seed = args.episodes, 1000 + seed
                returns = pl.deep.evaluate(agent, env_id, episodes, eval_seed)  # type: ignore[arg-type]
                ret = float(np.mean(returns))
                print(f"{env_id} {algo} {lib} seed {seed}: {ret:.1f} ({sec:.0f} s)", flush=True)
                if args.results:  # one JSON line per run, for --summarize
                    with open(args.results, "a") as f:
                        f.write(json.dumps(dict(
                            env=env_id, algo=algo, lib=lib, seed=seed, steps=steps,
                            episodes=episodes, mean_return=ret, seconds=sec,
                            commit=_commit(), machine=processor(),
                            finished=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                        )) + "\n")  # fmt: skip
                zoo = f"{published[algo]:.0f}" if algo in published else ""
                rows.append(f"| {algo.upper()} | {lib} | {seed} | {ret:.1f} | {zoo} | {sec:.0f} |")
    loads.append(_load())
    body = (
        f"policylab's zoo defaults for {env_id} (`policylab train sac|td3 {env_id}`), "
        f"{steps:,} steps, then the mean return of {args.episodes} deterministic episodes of "
        "the final policy (the zoo's published Pendulum-v1 numbers are means over 150,000 "
        "evaluation steps, 750 episodes, of the final deterministic policy). Load before and "
        "after:\n\n"
        f"    {loads[0]}\n    {loads[1]}\n\n" + "\n".join(rows)
    )
    print(body)
    if args.write:
        write_section(
            f"Deep RL: SAC and TD3 on {env_id}",
            f"python benchmarks/bench_continuous.py --quality {env_id} --seeds {args.seeds} "
            f"--episodes {args.episodes}"
            + (" --sb3" if args.sb3 else "")
            + (f" --libs {' '.join(libs)}" if args.libs else ""),
            body,
        )


def read_records(paths: list[str] | list[Path]) -> list[dict[str, Any]]:
    """The runs of --results files (one JSON object a line), in file order.

    Exits naming the file and both lines when a seed of the same (env, algorithm,
    library, steps) is listed twice.
    """
    records: list[dict[str, Any]] = []
    seen: dict[tuple[str, str, str, int, int], str] = {}
    for path in paths:
        for number, line in enumerate(Path(path).read_text().splitlines(), 1):
            if line.strip():
                r = json.loads(line)
                run = (r["env"], r["algo"].upper(), r["lib"], int(r["steps"]), int(r["seed"]))
                where = f"{path}, line {number}"
                if run in seen:
                    sys.exit(f"{where}: seed {r['seed']} of {run[:4]} again (first: {seen[run]})")
                seen[run] = where
                records.append(r)
    return records


def read_runs(paths: list[str] | list[Path]) -> dict[tuple[str, str, str, int], list[float]]:
    """The mean returns of --results files by (env, ALGO, library, steps), in file order."""
    runs: dict[tuple[str, str, str, int], list[float]] = {}
    for r in read_records(paths):
        key = (r["env"], r["algo"].upper(), r["lib"], int(r["steps"]))
        runs.setdefault(key, []).append(float(r["mean_return"]))
    return runs


WALKERS = ("HalfCheetah-v5", "Hopper-v5", "Walker2d-v5")


def missing_runs(
    path: str | Path,
    envs: list[str],
    algos: list[str],
    libs: list[str],
    seeds: list[int],
    steps: int,
) -> list[tuple[str, str, str, int]]:
    """The (env, algo, library, seed) quality runs of ``steps`` env steps not yet in ``path``.

    In the order an interrupted queue leaves the most to compare: env by env, seed by
    seed, each algorithm's SB3 run before policylab's (SB3's take longer). A missing
    ``path`` has no runs yet.
    """
    done = {
        (r["env"], r["algo"].lower(), r["lib"], int(r["seed"]))
        for r in (read_records([path]) if Path(path).exists() else [])
        if int(r["steps"]) == steps
    }
    sb3_first = sorted(libs, key=lambda lib: lib != "SB3")
    return [
        (env, algo, lib, seed)
        for env in envs
        for seed in seeds
        for algo in algos
        for lib in sb3_first
        if (env, algo, lib, seed) not in done
    ]


def fill(args: argparse.Namespace) -> None:
    """Run the quality runs missing from ``args.fill``, one process pinned to each core."""
    import fcntl

    results = Path(args.fill)
    results.parent.mkdir(parents=True, exist_ok=True)
    held = results.open("a")  # one --fill a file at a time: two would run the same runs
    try:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        sys.exit(f"another --fill is running on {results}; wait for it or stop it first")
    steps = int(args.budget or 200_000)
    seeds = args.seed_list or list(range(args.seeds))
    queue = missing_runs(
        results, args.envs, args.algos, args.libs or ["policylab", "SB3"], seeds, steps
    )
    cores = args.cores or sorted(os.sched_getaffinity(0))
    logs = Path(args.log_dir)
    print(
        f"{len(queue)} runs of {steps:,} env steps missing from {results}; "
        f"one at a time on each of cores {', '.join(map(str, cores))}; logs in {logs}/",
        *(" ".join(map(str, run)) for run in queue),
        sep="\n  ",
        flush=True,
    )
    if args.dry_run:
        return
    logs.mkdir(parents=True, exist_ok=True)
    running: dict[int, tuple[subprocess.Popen[bytes], tuple[str, str, str, int], float]] = {}
    failed = 0
    while queue or running:
        for core in cores:
            if core not in running and queue:
                env, algo, lib, seed = run = queue.pop(0)
                command = [
                    sys.executable, __file__, "--quality", env, "--budget", str(steps),
                    "--algos", algo, "--libs", lib, "--seed-list", str(seed),
                    "--episodes", str(args.episodes), "--no-write", "--results", str(results),
                ]  # fmt: skip
                log = (logs / f"{env}-{algo}-{lib}-{seed}.log").open("wb")
                proc = subprocess.Popen(
                    command, stdout=log, stderr=subprocess.STDOUT,
                    preexec_fn=lambda core=core: os.sched_setaffinity(0, {core}),
                )  # fmt: skip
                log.close()
                running[core] = (proc, run, time.perf_counter())
                print(
                    f"{time.strftime('%H:%M:%S')} core {core}: start {' '.join(map(str, run))}",
                    flush=True,
                )
        time.sleep(args.poll)
        for core, (proc, run, start) in list(running.items()):
            if proc.poll() is not None:
                del running[core]
                minutes = (time.perf_counter() - start) / 60
                status = "done" if proc.returncode == 0 else f"FAILED (exit {proc.returncode})"
                failed += proc.returncode != 0
                print(
                    f"{time.strftime('%H:%M:%S')} core {core}: {status} "
                    f"{' '.join(map(str, run))} in {minutes:.0f} min",
                    flush=True,
                )
    if failed:
        sys.exit(f"{failed} runs failed; their logs are in {logs}/")
    summarize(argparse.Namespace(summarize=[results]))


def summarize(args: argparse.Namespace) -> None:
    """Mean return over seeds and its 95% bootstrap interval, from --results files."""
    import policylab as pl

    runs = read_runs(args.summarize)
    print(
        "| env | algorithm | library | env steps | seeds | mean return | 95% bootstrap interval "
        "| per seed |\n|---|---|---|---:|---:|---:|---|---|"
    )
    for (env, algo, lib, steps), rets in sorted(runs.items()):
        lo, hi = pl.stats.bootstrap_ci(np.array(rets), pl.stats.mean, reps=2000, seed=0)
        print(
            f"| {env} | {algo} | {lib} | {steps:,} | {len(rets)} | {np.mean(rets):.1f} "
            f"| [{lo:.1f}, {hi:.1f}] | {', '.join(f'{x:.1f}' for x in rets)} |"
        )
    print(
        "\nWhere both libraries have runs: the difference of the means and its 95% bootstrap"
        " interval (each library's seeds resampled on their own), the probability of"
        " improvement P(policylab > SB3) over seed pairs (ties count half), and one-sided"
        " permutation p-values of each library's mean being above the other's: exact (all"
        " splits of the pooled returns) up to 40 pooled runs, beyond that estimated from"
        f" {PERMUTATION_RESAMPLES:,} random splits and marked ≈.\n\n"
        "| env | algorithm | env steps | seeds (policylab, SB3) | policylab - SB3 "
        "| 95% bootstrap interval | P(policylab > SB3) | p, policylab above | p, SB3 above |\n"
        "|---|---|---:|---|---:|---|---:|---:|---:|"
    )
    for (env, algo, lib, steps), ours in sorted(runs.items()):
        theirs = runs.get((env, algo, "SB3", steps))
        if lib != "policylab" or not theirs:
            continue
        improvement = pl.stats.probability_of_improvement(ours, theirs)
        lo, hi = difference_ci(ours, theirs)
        print(
            f"| {env} | {algo} | {steps:,} | {len(ours)}, {len(theirs)} "
            f"| {np.mean(ours) - np.mean(theirs):+.1f} | [{lo:+.1f}, {hi:+.1f}] "
            f"| {improvement:.2f} "
            f"| {_p_cell(permutation_p(ours, theirs))} "
            f"| {_p_cell(permutation_p(theirs, ours))} |"
        )


def difference_ci(
    ours: list[float], theirs: list[float], reps: int = 2000, seed: int = 0
) -> tuple[float, float]:
    """95% percentile bootstrap interval of mean(ours) - mean(theirs).

    Each library's seeds are resampled with replacement on their own (the two are
    independent runs, not pairs), B = ``reps`` times; the interval is the 2.5% and 97.5%
    quantiles of the B differences of the resampled means.
    """
    import policylab as pl

    rng = np.random.default_rng(seed)
    a = pl.stats.bootstrap_distribution(np.array(ours), pl.stats.mean, reps=reps, seed=rng)
    b = pl.stats.bootstrap_distribution(np.array(theirs), pl.stats.mean, reps=reps, seed=rng)
    lo, hi = np.quantile(a - b, [0.025, 0.975])
    return float(lo), float(hi)


def _p_cell(result: tuple[float | None, bool]) -> str:
    """A ``permutation_p`` result for a table: "-" for none, "≈" before an estimate."""
    p, exact = result
    return "-" if p is None else f"{'' if exact else '≈'}{p:.3f}"


def _subset_sums(values: np.ndarray) -> list[np.ndarray]:
    """The sums of every subset of ``values``, sorted, listed by subset size (0 to len)."""
    masks = np.arange(2 ** len(values))
    members = (masks[:, None] >> np.arange(len(values))) & 1
    sums, sizes = members @ values, members.sum(axis=1)
    return [np.sort(sums[sizes == j]) for j in range(len(values) + 1)]


def _first_sum_floor(pooled: np.ndarray, k: int) -> float:
    """The observed first group's sum less 1e-9 of the values' scale, for rounding."""
    return float(pooled[:k].sum()) - 1e-9 * max(1.0, float(np.abs(pooled).sum()))


def exact_p(higher: list[float], lower: list[float]) -> float | None:
    """One-sided exact permutation p-value of mean(higher) - mean(lower) under no difference.

    The share of all C(n, k) splits of the n pooled values into a group of k = len(higher)
    and one of the rest whose difference of means is at least the observed one (what
    scipy's ``permutation_test`` with ``n_resamples=inf`` gives); None while a group has
    fewer than 2 values. With both sizes fixed, the difference of means
    S/k - (T - S)/(n - k) grows with the first group's sum S (T the pooled total), so the
    p-value counts the k-subsets with a sum of at least the observed one, within a
    tolerance of 1e-9 of the values' scale for rounding. They are counted meet in the
    middle, without listing the splits: the pooled values are cut in two halves A and B,
    every subset sum of each half is listed by size (2^(n/2) each), and for each j the
    pairs of a j-subset of A and a (k - j)-subset of B whose sums add up to at least S
    are counted by a binary search in B's sorted sums. 14 runs against 14 (40 million
    splits) take milliseconds; at most 40 pooled values.
    """
    from math import comb

    if min(len(higher), len(lower)) < 2:
        return None
    pooled = np.asarray([*higher, *lower], dtype=np.float64)
    n, k = len(pooled), len(higher)
    if n > 40:
        raise ValueError(f"exact_p lists 2^(n/2) subset sums: at most 40 values, got {n}")
    threshold = _first_sum_floor(pooled, k)
    first, second = _subset_sums(pooled[: n // 2]), _subset_sums(pooled[n // 2 :])
    count = 0
    for j in range(max(0, k - len(second) + 1), min(k, len(first) - 1) + 1):
        a, b = first[j], second[k - j]
        count += int(len(a) * len(b) - np.searchsorted(b, threshold - a, side="left").sum())
    return count / comb(n, k)


#: Random splits drawn by ``permutation_p`` when the pooled runs are too many to list.
PERMUTATION_RESAMPLES = 1_000_000


def permutation_p(
    higher: list[float],
    lower: list[float],
    *,
    resamples: int = PERMUTATION_RESAMPLES,
    seed: int = 0,
) -> tuple[float | None, bool]:
    """One-sided permutation p-value of mean(higher) - mean(lower), and whether it is exact.

    Up to 40 pooled values it is ``exact_p``: every split counted. Beyond, the splits are
    too many to count that way (36 runs against 36 have C(72, 36), about 4e20), and the
    p-value is estimated from B = ``resamples`` splits drawn uniformly at random (a random
    k-subset of the pooled values as the first group) as (1 + b) / (1 + B), b the drawn
    splits whose first group's sum is at least the observed one. Counting the observed
    split among the drawn ones keeps the estimate a valid p-value: when nothing differs
    it is at most alpha with probability at most alpha, and it is never 0 (Phipson and
    Smyth 2010, "Permutation p-values should never be zero"). Its standard error is at
    most 0.5 / sqrt(B), 0.0005 at the default B. Same seed, same estimate.

    Returns:
        ``(p, exact)``: the p-value (None while a group has fewer than 2 values) and
        True when every split was counted.
    """
    n = len(higher) + len(lower)
    if n <= 40 or min(len(higher), len(lower)) < 2:
        return exact_p(higher, lower), True
    pooled = np.asarray([*higher, *lower], dtype=np.float64)
    k = len(higher)
    threshold = _first_sum_floor(pooled, k)
    rng = np.random.default_rng(seed)
    at_least, chunk = 0, 20_000
    for start in range(0, resamples, chunk):
        rows = min(chunk, resamples - start)
        first = np.argpartition(rng.random((rows, n)), k - 1, axis=1)[:, :k]
        at_least += int((pooled[first].sum(axis=1) >= threshold).sum())
    return (1 + at_least) / (1 + resamples), False


@dataclass(frozen=True)
class PlannedComparison:
    """A comparison of two libraries fixed before its runs, read once when all are in.

    A p value read again each time runs are added rejects more often than its level when
    nothing differs; a plan fixed in advance (its env, algorithm, budget, seeds and
    rule) gives one clean test. ``not worse`` is a non-inferiority rule: the lower end
    of the 95% bootstrap interval of mean(policylab) - mean(SB3) above
    -``margin`` x mean(SB3); ``behind`` is the exact one-sided permutation test of SB3's
    mean above policylab's at the 5% level. Both are reported, so a run that is behind
    by less than the margin says so.
    """

    env: str
    algo: str
    steps: int
    seeds: tuple[int, ...]
    margin: float
    fixed: str  # when the plan was fixed, before any of its returns was known

    def read(self, records: list[dict[str, Any]]) -> str:
        """The plan's result from ``read_records`` output, or how many runs are still out."""
        got: dict[str, dict[int, float]] = {"policylab": {}, "SB3": {}}
        for r in records:
            if (
                r["env"] == self.env
                and r["algo"].upper() == self.algo.upper()
                and int(r["steps"]) == self.steps
                and r["lib"] in got
                and int(r["seed"]) in self.seeds
            ):
                got[r["lib"]][int(r["seed"])] = float(r["mean_return"])
        n = len(self.seeds)
        head = (
            f"planned test ({self.env} {self.algo.upper()} at {self.steps:,} steps, seeds "
            f"{self.seeds[0]} to {self.seeds[-1]}, fixed {self.fixed})"
        )
        if any(len(v) < n for v in got.values()):
            return (
                f"{head}: {len(got['policylab'])} of {n} policylab runs and {len(got['SB3'])} "
                f"of {n} SB3 runs are in; it is read once, when all {2 * n} are"
            )
        ours = [got["policylab"][s] for s in self.seeds]
        sb3 = [got["SB3"][s] for s in self.seeds]
        p = exact_p(sb3, ours)
        assert p is not None  # a plan has at least 2 seeds
        lo, hi = difference_ci(ours, sb3)
        bound = -self.margin * float(np.mean(sb3))
        not_worse = lo > bound
        behind = p < 0.05
        verdict = (
            f"{'not worse' if not_worse else 'not shown not worse'} (interval's lower end "
            f"{lo:+.1f} {'above' if not_worse else 'at or below'} {bound:+.1f}, "
            f"-{self.margin:.0%} of SB3's mean); SB3 "
            f"{'ahead' if behind else 'not shown ahead'} at the 5% level (p = {p:.3f})"
        )
        return (
            f"{head}: SB3 {np.mean(sb3):.1f} against policylab {np.mean(ours):.1f}, "
            f"policylab - SB3 {np.mean(ours) - np.mean(sb3):+.1f}, 95% bootstrap interval "
            f"[{lo:+.1f}, {hi:+.1f}]: {verdict}"
        )


#: HalfCheetah-v5 TD3's test, fixed after the table's 14 runs each: 20 new seeds of both
#: libraries, "not worse" within 10% of SB3's mean.
TD3_CHEETAH_PLAN = PlannedComparison(
    env="HalfCheetah-v5",
    algo="td3",
    steps=200_000,
    seeds=tuple(range(16, 36)),
    margin=0.10,
    fixed="6 December 2026",
)


def walker(args: argparse.Namespace) -> None:
    """Forward velocity, episode lengths and returns of a walking run; its learning curve."""
    import csv

    import gymnasium as gym

    import policylab as pl
    from policylab.deep.common.walking import WalkingReward
    from policylab.plot import run_curves_figure, save_figure

    run = Path(args.walker)
    agent = pl.deep.load(run)
    doc = json.loads((run / "run.json").read_text())
    v_max = float(doc.get("reward", {}).get("v_max", 3.0))
    env = WalkingReward(gym.make(str(agent.env_id)), v_max=v_max)
    dt = float(env.unwrapped.dt)  # type: ignore[attr-defined]
    rows = []
    for i in range(args.episodes):
        obs, _ = env.reset(seed=1000 + i)
        x0 = float(env.unwrapped.data.qpos[0])  # type: ignore[attr-defined]
        steps, env_ret, walk_ret, vx = 0, 0.0, 0.0, []
        done = term = False
        while not done:
            obs, r, term, trunc, info = env.step(agent.predict(obs))
            steps += 1
            walk_ret += float(r)
            env_ret += float(info["env_reward"])
            vx.append(float(info["x_velocity"]))
            done = term or trunc
        x1 = float(env.unwrapped.data.qpos[0])  # type: ignore[attr-defined]
        rows.append((steps, (x1 - x0) / (steps * dt), float(np.mean(vx)), walk_ret, env_ret, term))
        print(
            f"episode {i} (reset seed {1000 + i}): {steps} steps, {x1 - x0:.2f} m in "
            f"{steps * dt:.1f} s = {rows[-1][1]:.2f} m/s (mean x_velocity {rows[-1][2]:.2f}), "
            f"walking return {walk_ret:.1f}, env return {env_ret:.1f}",
            flush=True,
        )
    a = np.array(rows)
    print(
        f"{agent.env_id}, {agent.num_timesteps:,} env steps, {args.episodes} greedy episodes: "
        f"{a[:, 0].mean():.0f} steps on average ({int(a[:, 5].sum())} fell), forward "
        f"velocity {a[:, 1].mean():.2f} m/s (min {a[:, 1].min():.2f}, max {a[:, 1].max():.2f}), "
        f"walking return {a[:, 3].mean():.1f}, env return {a[:, 4].mean():.1f}"
    )
    with (run / "progress.csv").open() as f:
        prog = [r for r in csv.DictReader(f) if r.get("recent_return")]
    x = np.array([float(r["step"]) for r in prog])
    y = np.array([float(r["recent_return"]) for r in prog])
    fig = run_curves_figure(
        {f"{agent.env_id}, {doc.get('algo', '').upper()}": {"walking reward": [(x, y)]}},
        x_label="env step",
        y_label="return of the recent training episodes",
        title=f"Learning to walk: {agent.env_id} under the walking reward (v_max {v_max:g} m/s)",
    )
    out = save_figure(fig, args.figure or run / "learning_curve.png")
    print(f"wrote {out}")


def main() -> None:
    warnings.filterwarnings("ignore")  # both libraries' deprecation chatter, in long runs
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--env", default="HalfCheetah-v5")
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--learning-starts", type=int, default=1000)
    p.add_argument("--buffer-size", type=int, default=100_000)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--algos", nargs="+", default=["sac", "td3"])
    p.add_argument("--pendulum", action="store_true", help="the Pendulum-v1 quality table")
    p.add_argument(
        "--quality", metavar="ENV_ID",
        help="the quality table on ENV_ID: train with the zoo's settings, evaluate greedily",
    )  # fmt: skip
    p.add_argument("--budget", type=int, help="env steps of each --quality run (default: zoo's)")
    p.add_argument("--results", help="append each --quality run's result to this JSON-lines file")
    p.add_argument(
        "--summarize", nargs="+", metavar="FILE",
        help="instead: mean and bootstrap interval over seeds of --results files, and "
        "policylab against SB3 where both have runs (P(policylab > SB3), permutation tests)",
    )  # fmt: skip
    p.add_argument(
        "--fill", metavar="FILE",
        help="instead: run the quality runs (--envs x --algos x --libs x seeds, --budget "
        "steps, default 200,000) missing from FILE, one process pinned to each of --cores, "
        "appending each result to FILE; run it again to go on after an interruption",
    )  # fmt: skip
    p.add_argument("--envs", nargs="+", default=list(WALKERS), help="the envs of --fill")
    p.add_argument(
        "--cores", type=int, nargs="+",
        help="--fill: the CPU cores to run on, one run each (default: every core allowed)",
    )  # fmt: skip
    p.add_argument("--log-dir", default="runs/quality-logs", help="--fill: each run's output")
    p.add_argument("--dry-run", action="store_true", help="--fill: list the missing runs, run none")
    p.add_argument("--poll", type=float, default=10.0, help=argparse.SUPPRESS)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--seed-list", type=int, nargs="+", help="these seeds instead of --seeds")
    p.add_argument(
        "--episodes", type=int, default=750,
        help="greedy evaluation episodes of each run (default: 750 on Pendulum-v1, else 10)",
    )  # fmt: skip
    p.add_argument("--sb3", action="store_true", help="--quality: also train SB3")
    p.add_argument(
        "--libs", nargs="+", choices=["policylab", "SB3"],
        help="--quality, --fill: these libraries only (default: policylab, and SB3 with --sb3; "
        "--fill: both)",
    )  # fmt: skip
    p.add_argument(
        "--per-update", type=int, default=0, metavar="N",
        help="instead: N single updates of each library, alternating, CPU ms each",
    )  # fmt: skip
    p.add_argument(
        "--walker", metavar="RUN_DIR",
        help="instead: forward velocity and learning curve of a walking run (--episodes of them)",
    )  # fmt: skip
    p.add_argument("--figure", help="learning-curve file for --walker")
    p.add_argument("--no-write", dest="write", action="store_false")
    p.add_argument(
        "--save-dir", help="--quality: save each run's final policy in this folder (.pt, SB3 .zip)"
    )
    args = p.parse_args()
    if args.pendulum:
        args.quality = "Pendulum-v1"
    if (
        args.walker or args.fill or args.quality not in (None, "Pendulum-v1")
    ) and args.episodes == 750:
        args.episodes = 10  # 750 is the Pendulum protocol's; a walker's episode is longer
    if args.summarize:
        summarize(args)
    elif args.fill:
        fill(args)
    elif args.walker:
        walker(args)
    elif args.per_update:
        per_update(args)
    else:
        quality(args) if args.quality else speed(args)


if __name__ == "__main__":
    main()
