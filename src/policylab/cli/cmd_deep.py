"""``policylab train``, ``policylab eval`` and ``policylab record``: deep RL from a shell.

torch is imported only when one of these commands runs, so the rest of the CLI starts fast.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from policylab.cli.common import console, err_console, print_json
from policylab.exceptions import InvalidArgumentError, RunFolderError, TrainingInterrupted
from policylab.validation import (
    check_count,
    check_output_dir,
    check_output_file,
    check_seed,
    normalize_name,
)

if TYPE_CHECKING:
    from policylab.deep.common.agent import Agent
    from policylab.runs import RunFolder

__all__ = ["RESUME_SETTABLE", "register"]

RESUME_SETTABLE = ("checkpoint_every", "log_interval", "torch_threads")
"""Config fields that ``--set`` may change on ``--resume``: they change how the run is
saved and logged, or how fast it computes, never what it learns."""

_TRAIN_HELP = (
    "Train a deep RL agent (ALGO: ppo, dqn, sac or td3) on a Gymnasium environment.\n\n"
    "Starts from tuned defaults for the environment (rl-baselines3-zoo's settings for classic "
    "control, Box2D, MuJoCo and Atari, see policylab.deep.zoo), so "
    "`policylab train ppo CartPole-v1` solves CartPole with no other flag; an environment "
    "without tuned settings gets the generic defaults, with a note.\n\n"
    "The run folder (--out) gets run.json, progress.csv, TensorBoard events (tb/) and "
    "checkpoint.pt, which `policylab eval` and `policylab record` read and --resume continues. "
    "It belongs to one command at a time (a second one is refused). A checkpoint is saved "
    "every checkpoint_every steps (10,000 by default), at the end, and on Ctrl-C (or "
    "SIGTERM), which stops with exit code 130 (143); progress.csv always matches the "
    "checkpoint.\n\n"
    "A folder that holds a run is never reused: pass --resume to continue it, or a new --out. "
    "--resume continues the run as it was started: its algorithm, environment, seed and "
    "config are kept, and --config or --set are refused, except --set for "
    f"{', '.join(RESUME_SETTABLE)}. --steps on resume extends the run "
    "(it counts all steps, so it cannot be below the steps taken); PPO's annealed learning "
    "rate then continues from the value it had reached down to 0 at the new end (a run "
    "annealed to 0 is not extended).\n\n"
    "Config fields (a JSON or TOML table in --config, or --set FIELD=VALUE) are those of "
    "policylab.deep.PPOConfig / DQNConfig / SACConfig / TD3Config; --dry-run lists them with "
    "their values and meaning.\n\n"
    "Board games: `train selfplay-td tic-tac-toe --out DIR` (Sutton & Barto's self-play TD "
    "learner) and `train alphazero tic-tac-toe|connect-four --out DIR` (--set FIELD=VALUE "
    "over policylab.games.alphazero.AlphaZeroConfig)."
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
    algo: Annotated[
        str,
        typer.Argument(
            help="Algorithm: ppo, dqn, sac or td3; board games: selfplay-td, alphazero."
        ),
    ],
    env_id: Annotated[
        str,
        typer.Argument(
            help="Gymnasium id: CartPole-v1, Pendulum-v1, Walker2d-v5, ALE/Pong-v5, ..."
        ),
    ],
    steps: Annotated[
        int | None,
        typer.Option(
            "--steps",
            help="Env steps to train in all (default: the tuned budget; on --resume, the run's).",
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(
            "--seed",
            help="Seed of the whole run: weights, envs, exploration (default: the config's, 0).",
        ),
    ] = None,
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
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help='Print one JSON object: {"algo", "env_id", "run_dir", "steps", "episodes", '
            '"seconds", "recent_return", "eval", "resumed_from"}.',
        ),
    ] = False,
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
    try:
        _train(
            algo, env_id, steps, seed, config, out, set_ or [], resume, eval_episodes,
            dry_run, progress, as_json, reward, v_max,
        )  # fmt: skip
    except TrainingInterrupted as e:
        typer.echo(f"interrupted at step {e.step:,}; continue with --resume", err=True)
        sys.exit(128 + e.signal)  # 130 for Ctrl-C, 143 for SIGTERM (the shells' convention)
    except KeyboardInterrupt:
        typer.echo(
            "interrupted; the last checkpoint saved (if any) is kept; continue with --resume",
            err=True,
        )
        sys.exit(130)


def _train(
    algo: str,
    env_id: str,
    steps: int | None,
    seed: int | None,
    config: Path | None,
    out: Path | None,
    set_items: list[str],
    resume: bool,
    eval_episodes: int,
    dry_run: bool,
    progress: bool,
    as_json: bool,
    reward: str = "env",
    v_max: float | None = None,
) -> None:
    from policylab.cli.cmd_games import GAME_LEARNERS, train_game

    if algo.lower() in GAME_LEARNERS:  # board games: train selfplay-td|alphazero GAME
        return train_game(
            algo.lower(),
            env_id,
            out=out,
            seed=0 if seed is None else seed,
            resume=resume,
            fields=_parse_set(set_items),
            progress=progress,
        )
    import numpy as np

    from policylab.deep.common.config import config_from_dict, load_config_file
    from policylab.deep.common.envs import check_env_id
    from policylab.deep.common.evaluation import evaluate
    from policylab.deep.common.walking import evaluate_walking, reward_env, run_reward
    from policylab.deep.io import resume as resume_run
    from policylab.deep.zoo import ALGORITHMS, default_config, has_tuned_settings
    from policylab.runs import CHECKPOINT, RUN_JSON, RUN_MARKERS, RunFolder

    algo = normalize_name(algo)
    if algo not in ALGORITHMS:
        raise InvalidArgumentError(
            f"unknown algorithm {algo!r}; known: {', '.join(sorted(ALGORITHMS))}"
        )
    cls = ALGORITHMS[algo]
    if steps is not None:
        check_count(steps, "--steps")
    check_count(eval_episodes, "--eval-episodes", minimum=0)
    check_seed(seed, "--seed")
    if out is not None:
        check_output_dir(out, "--out")
    info = err_console if as_json else console
    overrides = _parse_set(set_items)
    command = f"policylab train {algo} {env_id}"
    t0 = time.perf_counter()
    resumed_from: int | None = None
    if resume:
        if config is not None:
            raise InvalidArgumentError(
                "--config cannot change a resumed run (it keeps the config it was started "
                "with); start a new run with --out to train with other settings"
            )
        _check_resume_overrides(overrides)
        run_dir = out or _default_run_dir(algo, env_id, seed or 0)
        run = RunFolder(run_dir, resume=True, markers=RUN_MARKERS, command=command)
        with run:
            _check_same_run(run, algo, env_id, run.info or {})
            if reward != "env" or v_max is not None:  # allowed only if it repeats the run's
                kept = run_reward(run.file(RUN_JSON))
                if kept.get("name") != reward or v_max not in (None, kept.get("v_max")):
                    raise InvalidArgumentError(
                        f"--reward {reward}"
                        + ("" if v_max is None else f" --v-max {v_max}")
                        + f" differs from the run's reward {kept}; a resumed run keeps the "
                        "reward it was started with (leave out --reward and --v-max)"
                    )
            if not run.file(CHECKPOINT).is_file():
                raise RunFolderError(
                    f"{str(run_dir)!r} holds a run that stopped before its first checkpoint; "
                    "there is nothing to resume: remove the folder or choose another --out"
                )
            agent = resume_run(run_dir)  # whatever its algorithm, to name it in a refusal
            _check_same_run(run, algo, env_id, {"algo": agent.algo, "env_id": agent.env_id})
            if seed is not None and seed != agent.config.seed:
                raise InvalidArgumentError(
                    f"--seed {seed} differs from the run's seed {agent.config.seed}; a resumed "
                    "run keeps its seed (leave out --seed, or start a new run with --out)"
                )
            if overrides:
                agent.config = config_from_dict(cls.config_class, overrides, base=agent.config)
            total = steps if steps is not None else agent.target_steps
            _check_resume_steps(agent, total, run_dir)
            resumed_from = agent.num_timesteps
            if dry_run:
                _config_table(cls, agent.config, f"{algo} on {env_id}: {total:,} steps", info)
                return
            _start_line(info, run, agent, total, resumed=True)
            agent.learn(total, progress=progress and not as_json, run_dir=run)
    else:
        check_env_id(env_id)
        fields, tuned_steps = default_config(algo, env_id)
        if not has_tuned_settings(algo, env_id):
            err_console.print(
                f"note: no tuned hyperparameters for {algo} on {env_id}; using generic defaults",
                markup=False,
                highlight=False,
                soft_wrap=True,
            )
        file_fields = load_config_file(config) if config is not None else {}
        file_steps = file_fields.pop("steps", None)
        if file_steps is not None:
            check_count(file_steps, f"steps in {str(config)!r}")
        fields.update(file_fields)
        fields.update(overrides)
        if seed is not None:  # else the seed of --config or --set, or the default 0
            fields["seed"] = seed
        total = steps or file_steps or tuned_steps or 100_000
        cfg = config_from_dict(cls.config_class, fields)
        if dry_run:
            _config_table(cls, cfg, f"{algo} on {env_id}: {total:,} steps", info)
            return
        run_dir = out or _default_run_dir(algo, env_id, cfg.seed)
        check_output_dir(run_dir, "--out")
        run = RunFolder(run_dir, resume=False, markers=RUN_MARKERS, command=command)
        if run.holds_run():  # said before any work; the lock re-checks it
            run.open()
        agent = cls(reward_env(env_id, reward, cfg.n_envs, v_max), config=cfg)
        with run:
            _start_line(info, run, agent, total, resumed=False)
            agent.learn(total, progress=progress and not as_json, run_dir=run)
    seconds = time.perf_counter() - t0
    recent = agent.recent_mean_return()
    returns = None
    if eval_episodes > 0:
        returns = evaluate(agent, episodes=eval_episodes, seed=agent.config.seed + 10_000)
    if as_json:
        print_json(
            {
                "algo": algo,
                "env_id": env_id,
                "run_dir": str(run_dir),
                "steps": agent.num_timesteps,
                "episodes": agent.episodes,
                "seconds": seconds,
                "recent_return": recent,
                "eval": None
                if returns is None
                else {
                    "mean": float(np.mean(returns)),
                    "std": float(np.std(returns)),
                    "returns": [float(x) for x in returns],
                },
                "resumed_from": resumed_from,
            }
        )
        return
    table = Table(title=f"{algo} on {env_id}")
    table.add_column("")
    table.add_column("", justify="right")
    table.add_row("env steps", f"{agent.num_timesteps:,}")
    table.add_row("episodes", f"{agent.episodes:,}")
    table.add_row("wall-clock", f"{seconds:.1f} s")
    table.add_row(
        "mean return, last 100 training episodes", "-" if recent is None else f"{recent:.2f}"
    )
    if returns is not None:
        table.add_row(
            f"evaluation, {eval_episodes} episodes (greedy)",
            f"{np.mean(returns):.2f} ± {np.std(returns):.2f}",
        )
        w = evaluate_walking(
            agent, Path(run_dir) / "run.json", eval_episodes, agent.config.seed + 10_000
        )
        if w is not None:
            table.add_row("same episodes, walking reward", f"{np.mean(w):.2f} ± {np.std(w):.2f}")
    table.add_row("run folder", str(run_dir))
    console.print(table)


def _default_run_dir(algo: str, env_id: str, seed: int) -> Path:
    return Path("runs") / f"{algo}-{env_id.replace('/', '_')}-s{seed}"


def _check_resume_overrides(overrides: dict[str, Any]) -> None:
    refused = sorted(set(overrides) - set(RESUME_SETTABLE))
    if refused:
        raise InvalidArgumentError(
            f"--set {', '.join(refused)} cannot change a resumed run (it keeps the config it "
            f"was started with); on --resume --set may change only {', '.join(RESUME_SETTABLE)}"
        )


def _check_same_run(run: RunFolder, algo: str, env_id: str, doc: dict[str, Any]) -> None:
    """Refuse to resume a run of another algorithm or env (named by run.json or the agent)."""
    was_algo, was_env = doc.get("algo"), doc.get("env_id")
    if was_algo is None or was_env is None:  # no run.json: checked on the loaded agent
        return
    if (was_algo, was_env) != (algo, env_id):
        raise RunFolderError(
            f"{str(run.path)!r} is a {was_algo} run on {was_env}, not {algo} on {env_id}; "
            f"--resume continues a run as it is: policylab train {was_algo} {was_env} "
            f"--out {run.path} --resume"
        )


def _check_resume_steps(agent: Agent, total: int, run_dir: Path) -> None:
    done = agent.num_timesteps
    if total < done:
        raise InvalidArgumentError(
            f"--steps {total:,} is below the {done:,} steps the run in {str(run_dir)!r} has "
            f"taken; --steps counts all steps of the run (pass more than {done:,} to extend it)"
        )
    annealed_out = getattr(agent.config, "anneal_lr", False) and agent.progress_remaining <= 0
    if total > agent.target_steps and annealed_out:
        raise InvalidArgumentError(
            f"the run in {str(run_dir)!r} has annealed its learning rate to 0 at step "
            f"{agent.target_steps:,}; extending it would not learn. Start a new run with more "
            "--steps"
        )


def _start_line(info: Console, run: RunFolder, agent: Agent, total: int, resumed: bool) -> None:
    for line in _lock_notes(run):
        info.print(line, markup=False, highlight=False, soft_wrap=True)
    every = agent.config.checkpoint_every
    ckpt = f"checkpoint every {every:,} steps" if every else "checkpoint at the end"
    if resumed:
        head = f"resuming {run.path} at step {agent.num_timesteps:,} of {total:,}"
    else:
        head = f"training {agent.algo} on {agent.env_id} for {total:,} steps in {run.path}"
    info.print(f"{head}; {ckpt} and on Ctrl-C", markup=False, highlight=False, soft_wrap=True)


def _lock_notes(run: RunFolder) -> list[str]:
    notes = []
    if run.stale_owner is not None:
        notes.append(
            f"note: took over the lock left by process {run.stale_owner.get('pid')}, "
            "which is no longer running"
        )
    if run.removed_temps:
        notes.append(
            f"note: removed {len(run.removed_temps)} temporary file(s) of an interrupted write"
        )
    return notes


def _config_table(cls: type[Agent], cfg: Any, title: str, info: Console) -> None:
    from policylab.deep.common.config import config_help

    table = Table(title=title)
    for col in ("field", "value", "meaning"):
        table.add_column(col)
    for name, help_text, _ in config_help(cls.config_class):
        table.add_row(name, str(getattr(cfg, name)), help_text)
    info.print(table)


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

    check_count(episodes, "--episodes")
    check_seed(seed, "--seed")
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
        Path | None,
        typer.Option(
            "--out",
            help="File to write; its suffix picks the format: .gif, .png (animated PNG) or "
            ".webp (default RUN_DIR/episode.gif).",
        ),
    ] = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the recorded episode.")] = 0,
    max_steps: Annotated[
        int, typer.Option("--max-steps", help="Stop the episode after this many steps.")
    ] = 1000,
    fps: Annotated[int, typer.Option("--fps", help="Frames per second of the animation.")] = 30,
    every: Annotated[
        int, typer.Option("--every", help="Keep every k-th frame (smaller files).")
    ] = 1,
) -> None:
    """Write an animation (GIF, PNG or WebP) of one greedy episode of a trained agent."""
    from policylab.deep.io import checkpoint_path, load
    from policylab.deep.mujoco_gl import use_offscreen_gl
    from policylab.deep.record import ANIMATION_FORMATS, record_gif

    check_seed(seed, "--seed")
    check_count(max_steps, "--max-steps")
    check_count(fps, "--fps")
    check_count(every, "--every")
    if out is not None:  # checked before the checkpoint is read and the episode played
        check_output_file(out, "--out", suffixes=ANIMATION_FORMATS)
    target = out or checkpoint_path(run_dir).parent / "episode.gif"
    agent = load(run_dir)
    use_offscreen_gl(agent.env_id)  # MuJoCo walkers render headless (EGL or OSMesa)
    ret, n = record_gif(agent, target, seed=seed, max_steps=max_steps, fps=fps, every=every)
    console.print(f"wrote {target}: {n} frames, episode return {ret:.2f}")


def register(app: typer.Typer) -> None:
    """Add the deep RL subcommands to the ``policylab`` app."""
    app.command("train", help=_TRAIN_HELP)(train_command)
    app.command("eval")(eval_command)
    app.command("record")(record_command)
