"""``policylab train``, ``policylab eval`` and ``policylab record``: deep RL from a shell.

torch is imported only when one of these commands runs, so the rest of the CLI starts fast.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from policylab.cli.common import console, print_json
from policylab.exceptions import InvalidArgumentError

__all__ = ["register"]

_TRAIN_HELP = (
    "Train a deep RL agent (ALGO: ppo, dqn, sac or td3) on a Gymnasium environment.\n\n"
    "Starts from tuned defaults for the environment (rl-baselines3-zoo's settings for classic "
    "control, Box2D, MuJoCo and Atari, see policylab.deep.zoo), so "
    "`policylab train ppo CartPole-v1` solves CartPole with no other flag.\n\n"
    "The run folder (--out) gets run.json, progress.csv, TensorBoard events (tb/) and "
    "checkpoint.pt, which `policylab eval` and `policylab record` read and --resume continues.\n\n"
    "Config fields (a JSON or TOML table in --config, or --set FIELD=VALUE) are those of "
    "policylab.deep.PPOConfig / DQNConfig / SACConfig / TD3Config; --dry-run lists them with "
    "their values and meaning."
)


def _parse_set(items: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise InvalidArgumentError(f"--set takes FIELD=VALUE; got {item!r}")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def train_command(
    algo: Annotated[str, typer.Argument(help="Algorithm: ppo, dqn, sac or td3.")],
    env_id: Annotated[
        str,
        typer.Argument(
            help="Gymnasium id: CartPole-v1, Pendulum-v1, Walker2d-v5, ALE/Pong-v5, ..."
        ),
    ],
    steps: Annotated[
        int | None,
        typer.Option("--steps", help="Env steps to train in all (default: the tuned budget)."),
    ] = None,
    seed: Annotated[
        int, typer.Option("--seed", help="Seed of the whole run (weights, envs, exploration).")
    ] = 0,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config", help="JSON or TOML file of config fields (over the tuned defaults)."
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", help="Run folder (default runs/ALGO-ENV-sSEED).")
    ] = None,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="Override one config field: --set n_envs=16 (repeatable)."),
    ] = None,
    resume: Annotated[
        bool, typer.Option("--resume", help="Continue the run in --out from its last checkpoint.")
    ] = False,
    eval_episodes: Annotated[
        int,
        typer.Option(
            "--eval-episodes", help="Episodes of the evaluation after training (0: none)."
        ),
    ] = 10,
    dry_run: Annotated[
        bool, typer.Option("--dry-run", help="Print the resolved config and exit without training.")
    ] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Show the progress bar.")
    ] = True,
    reward: Annotated[
        str,
        typer.Option(
            "--reward",
            help="Reward to learn from: env (the env's own) or walking (the walking reward of "
            "Heess et al. 2017 on HalfCheetah, Hopper, Walker2d, Ant, Humanoid).",
        ),
    ] = "env",
    v_max: Annotated[
        float | None,
        typer.Option("--v-max", help="Speed cap in m/s of the walking reward (default 3)."),
    ] = None,
) -> None:
    import numpy as np

    from policylab.deep.common.config import config_help, load_config_file
    from policylab.deep.common.evaluation import evaluate
    from policylab.deep.common.walking import evaluate_walking, reward_env
    from policylab.deep.zoo import ALGORITHMS, default_config

    algo = algo.lower()
    if algo not in ALGORITHMS:
        raise InvalidArgumentError(
            f"unknown algorithm {algo!r}; known: {', '.join(sorted(ALGORITHMS))}"
        )
    cls = ALGORITHMS[algo]
    run_dir = out or Path("runs") / f"{algo}-{env_id.replace('/', '_')}-s{seed}"
    t0 = time.perf_counter()
    if resume:
        agent = cls.resume(run_dir)
        total = steps or agent.target_steps
        console.print(f"resuming {run_dir} at step {agent.num_timesteps:,} of {total:,}")
    else:
        fields, tuned_steps = default_config(algo, env_id)
        file_fields = load_config_file(config) if config is not None else {}
        file_steps = file_fields.pop("steps", None)
        fields.update(file_fields)
        fields.update(_parse_set(set_ or []))
        fields["seed"] = seed
        total = steps or file_steps or tuned_steps or 100_000
        if dry_run:
            from policylab.deep.common.config import config_from_dict

            cfg = config_from_dict(cls.config_class, fields)
            table = Table(title=f"{algo} on {env_id}: {total:,} steps")
            for col in ("field", "value", "meaning"):
                table.add_column(col)
            for name, help_text, _ in config_help(cls.config_class):
                table.add_row(name, str(getattr(cfg, name)), help_text)
            console.print(table)
            return
        if (run_dir / "checkpoint.pt").exists():
            raise InvalidArgumentError(
                f"{str(run_dir)!r} already holds a run; pass --resume to continue it "
                "or --out for a new folder"
            )
        agent = cls(reward_env(env_id, reward, int(fields.get("n_envs", 1)), v_max), **fields)
    agent.learn(int(total), progress=progress, run_dir=run_dir)
    seconds = time.perf_counter() - t0
    table = Table(title=f"{algo} on {env_id}")
    table.add_column("")
    table.add_column("", justify="right")
    table.add_row("env steps", f"{agent.num_timesteps:,}")
    table.add_row("episodes", f"{agent.episodes:,}")
    table.add_row("wall-clock", f"{seconds:.1f} s")
    recent = agent.recent_mean_return()
    table.add_row(
        "mean return, last 100 training episodes", "-" if recent is None else f"{recent:.2f}"
    )
    if eval_episodes > 0:
        r = evaluate(agent, episodes=eval_episodes, seed=seed + 10_000)
        table.add_row(
            f"evaluation, {eval_episodes} episodes (greedy)", f"{np.mean(r):.2f} ± {np.std(r):.2f}"
        )
        w = evaluate_walking(agent, run_dir / "run.json", eval_episodes, seed + 10_000)
        if w is not None:
            table.add_row("same episodes, walking reward", f"{np.mean(w):.2f} ± {np.std(w):.2f}")
    table.add_row("run folder", str(run_dir))
    console.print(table)


def eval_command(
    run_dir: Annotated[
        Path, typer.Argument(help="A run folder from `policylab train` or a checkpoint file.")
    ],
    episodes: Annotated[int, typer.Option("--episodes", help="Number of whole episodes.")] = 10,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the evaluation episodes.")] = 0,
    stochastic: Annotated[
        bool, typer.Option("--stochastic", help="Sample actions instead of acting greedily.")
    ] = False,
    as_json: Annotated[
        bool, typer.Option("--json", help='Print {"mean", "std", "returns"} as JSON.')
    ] = False,
) -> None:
    """Evaluate a trained agent: the return of each of N episodes, their mean and std."""
    import numpy as np

    from policylab.deep.common.evaluation import evaluate
    from policylab.deep.common.walking import evaluate_walking
    from policylab.deep.io import checkpoint_path, load

    agent = load(run_dir)
    r = evaluate(agent, episodes=episodes, seed=seed, deterministic=not stochastic)
    run_json = checkpoint_path(run_dir).parent / "run.json"
    w = evaluate_walking(agent, run_json, episodes, seed, deterministic=not stochastic)
    if as_json:
        doc: dict[str, Any] = {
            "mean": float(np.mean(r)), "std": float(np.std(r)), "returns": [float(x) for x in r]
        }  # fmt: skip
        if w is not None:  # the same episodes under the walking reward the run trained on
            doc["walking"] = {
                "mean": float(np.mean(w)), "std": float(np.std(w)), "returns": [float(x) for x in w]
            }  # fmt: skip
        print_json(doc)
        return
    table = Table(title=f"{agent.algo} on {agent.env_id}: {episodes} episodes")
    table.add_column("mean", justify="right")
    table.add_column("std", justify="right")
    table.add_column("min", justify="right")
    table.add_column("max", justify="right")
    table.add_row(*(f"{f(r):.2f}" for f in (np.mean, np.std, np.min, np.max)))
    console.print(table)
    if w is not None:
        console.print(
            f"the same episodes under the walking reward: mean {np.mean(w):.2f}, "
            f"std {np.std(w):.2f}"
        )


def record_command(
    run_dir: Annotated[
        Path, typer.Argument(help="A run folder from `policylab train` or a checkpoint file.")
    ],
    out: Annotated[
        Path | None, typer.Option("--out", help="GIF file to write (default RUN_DIR/episode.gif).")
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the recorded episode.")] = 0,
    max_steps: Annotated[
        int, typer.Option("--max-steps", help="Stop the episode after this many steps.")
    ] = 1000,
    fps: Annotated[int, typer.Option("--fps", help="Frames per second of the GIF.")] = 30,
    every: Annotated[
        int, typer.Option("--every", help="Keep every k-th frame (smaller GIFs).")
    ] = 1,
) -> None:
    """Write a GIF of one greedy episode of a trained agent (the env's rgb_array frames)."""
    from policylab.deep.io import checkpoint_path, load
    from policylab.deep.mujoco_gl import use_offscreen_gl
    from policylab.deep.record import record_gif

    agent = load(run_dir)
    use_offscreen_gl(agent.env_id)  # MuJoCo walkers render headless (EGL or OSMesa)
    target = out or checkpoint_path(run_dir).parent / "episode.gif"
    ret, n = record_gif(agent, target, seed=seed, max_steps=max_steps, fps=fps, every=every)
    console.print(f"wrote {target}: {n} frames, episode return {ret:.2f}")


def register(app: typer.Typer) -> None:
    """Add the deep RL subcommands to the ``policylab`` app."""
    app.command("train", help=_TRAIN_HELP)(train_command)
    app.command("eval")(eval_command)
    app.command("record")(record_command)
