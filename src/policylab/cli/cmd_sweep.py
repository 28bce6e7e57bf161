"""``policylab sweep`` and ``policylab tune``: many seeds, grids and searches on Ray Tune.

Ray is imported only when one of these commands runs, so the rest of the CLI starts fast.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from policylab.cli.common import console, err_console, print_json
from policylab.exceptions import InvalidArgumentError
from policylab.validation import check_count, check_output_dir, check_seed

__all__ = ["register"]

_EXTRA = {"allow_extra_args": True, "ignore_unknown_options": True}

_TRIALS_NOTE = (
    "Which trials run: for a deep algorithm (ppo, dqn, sac, td3) every (configuration, seed) "
    "is one Ray Tune trial, trained in segments of checkpoint_every steps, each continuing "
    "from the checkpoint the last one saved (so a trial whose worker dies is retried from its "
    "last checkpoint, up to --max-failures times, and ends as if it had never failed; each "
    "segment restarts the episodes in progress, as `train --resume` does). For a tabular "
    "algorithm, whose runs take milliseconds, one trial runs all seeds of a configuration in "
    "one compiled call (seed_study), and sweep.json still records every seed. Seed k is the "
    "run `policylab learn` / `train` gives with --seed k.\n\n"
    "Without --address a local Ray starts inside the command, sized to the machine "
    "(--num-cpus); with --address HOST:PORT it joins a running cluster (`ray start --head` "
    "on one node, `ray start --address=HEAD:6379` on the others); on several nodes --out "
    "must be on storage every node sees (NFS or similar).\n\n"
    "The folder --out gets sweep.json (every trial's configuration, seed, status, metrics and "
    "curve, and the statistics per configuration: IQM, mean, median, optimality gap with "
    "bootstrap intervals; rewritten atomically as trials finish; `policylab stats DIR` reads "
    "it), ray/ (Ray Tune's experiment) and trials/. It belongs to one command at a time; a "
    "folder that is not empty is refused. A killed or stopped command continues with "
    "--resume DIR: finished trials are kept, never run again; the others continue from their "
    "last checkpoints."
)

_SWEEP_HELP = (
    "Run ALGO on PROBLEM for N seeds and every combination of --set values, on Ray Tune.\n\n"
    "Takes the algorithm's own options as `policylab learn` or `train` takes them "
    "(--episodes, --alpha, --epsilon, ... for tabular algorithms; --steps for deep ones). "
    "--set KEY=V1,V2,... sweeps a key over values (repeatable: the grid is every "
    "combination); a key given one value is set for every trial. Keys are the algorithm's "
    "options (alpha, epsilon, n, ...) or, for deep algorithms, their config fields "
    "(learning_rate, n_envs, ...; see `policylab train ALGO ENV --dry-run`). The score of "
    "a run: the mean return of the last 10% of episodes (tabular; sweep.json also gives "
    "the error against the exact answer where the model is known) or of the last 100 "
    "training episodes (deep).\n\n" + _TRIALS_NOTE
)

_TUNE_HELP = (
    "Search hyperparameters of ALGO on PROBLEM: Optuna's TPE sampler (Ray Tune's "
    "OptunaSearch), with early stopping of bad trials (ASHA by default, or the median rule).\n\n"
    "--param NAME=DIST gives a searched key (repeatable), DIST one of loguniform:LOW,HIGH, "
    "uniform:LOW,HIGH, int:LOW,HIGH (both ends included) or choice:A,B,C. Every trial is one "
    "configuration scored over --seeds seeds (their mean). Tabular learners are scored "
    "against the exact answer of the planning layer (minus the RMS error of the learned "
    "values against q* for control, v_pi for prediction), so the search has a ground truth; "
    "deep learners by the mean return of their last 100 training episodes, reported after "
    "every checkpointed segment (what the early stopping compares). A tabular trial is one "
    "compiled call, so early stopping has nothing to stop there.\n\n" + _TRIALS_NOTE
)


#: Arguments and options that ``sweep`` and ``tune`` share.
Algorithm = Annotated[
    str | None,
    typer.Argument(help="Algorithm: a tabular one (q-learning, sarsa, ...) or ppo, dqn, sac, td3."),
]
Problem = Annotated[
    str | None,
    typer.Argument(
        help="Problem: a built-in name or a Gymnasium id with a model P (tabular), a "
        "Gymnasium id (deep)."
    ),
]
Address = Annotated[
    str | None,
    typer.Option("--address", help="Join the Ray cluster at HOST:PORT (default: a local Ray)."),
]
NumCpus = Annotated[
    int | None, typer.Option("--num-cpus", help="CPUs of the local Ray (default: all).")
]
MaxFailures = Annotated[
    int, typer.Option("--max-failures", help="Retries of a trial whose worker dies.")
]
Resume = Annotated[
    Path | None,
    typer.Option(
        "--resume", help="Continue the experiment in this folder (after a kill or a stop)."
    ),
]
AsJson = Annotated[
    bool,
    typer.Option(
        "--json",
        help="Print one JSON object: sweep.json's content (trials, statistics; best for tune) "
        "and out.",
    ),
]


def _default_out(command: str, algorithm: str, problem: str) -> Path:
    return Path("sweeps") / f"{command}-{algorithm}-{problem.replace('/', '_')}"


def _check_resume_args(
    algorithm: str | None, problem: str | None, extra: list[str], **given: Any
) -> None:
    """--resume continues the folder's own experiment: nothing else may be given."""
    named = [f"--{k.replace('_', '-')}" for k, v in given.items() if v not in (None, [], False)]
    if algorithm or problem or extra or named:
        what = ", ".join([*(x for x in (algorithm, problem) if x), *extra, *named])
        raise InvalidArgumentError(
            f"--resume DIR continues the experiment stored in DIR as it was started; leave "
            f"out {what} (only --address, --num-cpus and --json go with --resume)"
        )


def _need(algorithm: str | None, problem: str | None, command: str) -> tuple[str, str]:
    if not algorithm or not problem:
        raise InvalidArgumentError(
            f"{command} needs ALGO and PROBLEM (policylab {command} q-learning CliffWalking-v1 "
            "...), or --resume DIR"
        )
    return algorithm, problem


def _resumed(
    ctx: typer.Context,
    algorithm: str | None,
    problem: str | None,
    resume: Path | None,
    address: str | None,
    num_cpus: int | None,
    as_json: bool,
    **given: Any,
) -> bool:
    """Continue the experiment in ``resume`` if given (and say so); False for a new one."""
    from policylab.experiments import resume as resume_experiment

    if num_cpus is not None:
        check_count(num_cpus, "--num-cpus")
    if resume is None:
        return False
    _check_resume_args(algorithm, problem, list(ctx.args), **given)
    doc = resume_experiment(resume, address=address, num_cpus=num_cpus, progress=not as_json)
    _finish(doc, resume, as_json)
    return True


def _prepare(
    ctx: typer.Context,
    command: str,
    algorithm: str | None,
    problem: str | None,
    seeds: int,
    max_failures: int,
    out: Path | None,
) -> tuple[str, str, dict[str, Any], Path]:
    """(algorithm, problem, its own options, the sweep folder) of a new experiment, checked."""
    from policylab.experiments import parse_option_tokens

    algorithm, problem = _need(algorithm, problem, command)
    check_count(seeds, "--seeds")
    check_count(max_failures, "--max-failures", minimum=0)
    options = parse_option_tokens(algorithm, list(ctx.args))
    target = out or _default_out(command, algorithm.lower(), problem)
    check_output_dir(target, "--out")
    return algorithm, problem, options, target


def _show(doc: dict[str, Any], out: Path) -> None:
    """The statistics per configuration, the best one (tune), the folder."""
    stats = doc.get("statistics", {})
    table = Table(
        title=f"{doc['command']} {doc['algorithm']} on {doc['problem']}: score = "
        f"{doc['metric_description']}"
    )
    for col in ("configuration", "runs", "IQM [95% CI]", "mean [95% CI]", "median"):
        table.add_column(col, justify="left" if col == "configuration" else "right")

    def ci(s: dict[str, Any], key: str) -> str:
        v = s.get(key)
        if isinstance(v, dict):
            return f"{v['value']:.4g} [{v['low']:.4g}, {v['high']:.4g}]"
        return "-" if v is None else f"{v:.4g}"

    rows = sorted(stats.items(), key=lambda kv: kv[0])
    for label, s in rows[:40]:
        median = s.get("median")
        table.add_row(
            label,
            str(s.get("runs", "")),
            ci(s, "iqm"),
            ci(s, "mean"),
            f"{median['value']:.4g}" if isinstance(median, dict) else "-",
        )
    console.print(table)
    if len(rows) > 40:
        console.print(f"[dim]... {len(rows) - 40} more configurations in sweep.json[/]")
    best = doc.get("best")
    if best:
        console.print(
            f"best configuration: {best['config_label']} (score {best['score']:.4g} over "
            f"{best['seeds']} seeds)",
            markup=False,
            highlight=False,
        )
    console.print(f"sweep folder: {out} (sweep.json)", markup=False, highlight=False)


def _finish(doc: dict[str, Any], out: Path, as_json: bool) -> None:
    if as_json:
        print_json({**doc, "out": str(out)})
    else:
        _show(doc, out)
    unfinished = [t for t in doc["trials"] if t["status"] in ("PENDING", "RUNNING")]
    if unfinished:
        err_console.print(
            f"stopped with {len(unfinished)} run(s) unfinished; continue with --resume {out}",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
        sys.exit(130)
    errors = [t for t in doc["trials"] if t["status"] == "ERROR"]
    if errors:
        err_console.print(
            f"policylab: {len(errors)} run(s) failed after their retries (status ERROR in "
            f"{out / 'sweep.json'}; Ray's error files are under {out / 'ray'}); continue "
            f"with --resume {out}",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
        sys.exit(1)


def sweep_command(
    ctx: typer.Context,
    algorithm: Algorithm = None,
    problem: Problem = None,
    seeds: Annotated[int, typer.Option("--seeds", help="Seeds 0..N-1 of every configuration.")] = 8,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="KEY=V1,V2,...: sweep a key over values (repeatable)."),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Sweep folder (default sweeps/sweep-ALGO-PROBLEM)."),
    ] = None,
    address: Address = None,
    num_cpus: NumCpus = None,
    max_failures: MaxFailures = 2,
    resume: Resume = None,
    as_json: AsJson = False,
) -> None:
    from policylab.experiments import parse_set, sweep

    if _resumed(ctx, algorithm, problem, resume, address, num_cpus, as_json, set=set_, out=out):
        return
    algorithm, problem, options, target = _prepare(
        ctx, "sweep", algorithm, problem, seeds, max_failures, out
    )
    grid = parse_set(set_ or [])
    doc = sweep(
        algorithm,
        problem,
        seeds=seeds,
        out=target,
        options=options,
        grid=grid,
        address=address,
        num_cpus=num_cpus,
        max_failures=max_failures,
        progress=not as_json,
    )
    _finish(doc, target, as_json)


def tune_command(
    ctx: typer.Context,
    algorithm: Algorithm = None,
    problem: Problem = None,
    trials: Annotated[int, typer.Option("--trials", help="Configurations to try.")] = 20,
    param: Annotated[
        list[str] | None,
        typer.Option(
            "--param",
            help="NAME=DIST, DIST loguniform:LOW,HIGH | uniform:LOW,HIGH | int:LOW,HIGH | "
            "choice:A,B,C (repeatable).",
        ),
    ] = None,
    seeds: Annotated[
        int, typer.Option("--seeds", help="Seeds 0..K-1 every configuration is scored over.")
    ] = 3,
    set_: Annotated[
        list[str] | None,
        typer.Option("--set", help="KEY=VALUE: fix a key for every trial (repeatable)."),
    ] = None,
    scheduler: Annotated[
        str, typer.Option("--scheduler", help="Early stopping: asha, median or none.")
    ] = "asha",
    search_seed: Annotated[int, typer.Option("--search-seed", help="Seed of the TPE sampler.")] = 0,
    out: Annotated[
        Path | None, typer.Option("--out", help="Sweep folder (default sweeps/tune-ALGO-PROBLEM).")
    ] = None,
    address: Address = None,
    num_cpus: NumCpus = None,
    max_failures: MaxFailures = 2,
    resume: Resume = None,
    as_json: AsJson = False,
) -> None:
    from policylab.experiments import parse_distribution, parse_set, tune

    given = {"param": param, "set": set_, "out": out}
    if _resumed(ctx, algorithm, problem, resume, address, num_cpus, as_json, **given):
        return
    algorithm, problem, options, target = _prepare(
        ctx, "tune", algorithm, problem, seeds, max_failures, out
    )
    check_seed(search_seed, "--search-seed")
    space = dict(parse_distribution(p) for p in (param or []))
    if len(space) != len(param or []):
        raise InvalidArgumentError("--param names a key twice; give each key one distribution")
    fixed = parse_set(set_ or [])
    doc = tune(
        algorithm,
        problem,
        trials=trials,
        space=space,
        out=target,
        seeds=seeds,
        options=options,
        fixed=fixed,
        scheduler=scheduler,
        search_seed=search_seed,
        address=address,
        num_cpus=num_cpus,
        max_failures=max_failures,
        progress=not as_json,
    )
    _finish(doc, target, as_json)


def register(app: typer.Typer) -> None:
    """Add ``policylab sweep`` and ``policylab tune``."""
    app.command("sweep", help=_SWEEP_HELP, context_settings=_EXTRA)(sweep_command)
    app.command("tune", help=_TUNE_HELP, context_settings=_EXTRA)(tune_command)
