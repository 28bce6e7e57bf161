"""``policylab learn ALGO PROBLEM``: tabular learning from the command line.

One subcommand per algorithm of :mod:`policylab.tabular.registry` (``mc-prediction``,
``mc-control``, ``mc-off-policy``, and whatever else registers), each with the common
options and its own.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.table import Table

from policylab.cli.common import (
    console,
    emit_table,
    err_console,
    fmt_label,
    print_json,
    state_action_tables,
)
from policylab.exceptions import InvalidArgumentError
from policylab.tabular.common import MAX_EPISODES
from policylab.validation import (
    check_count,
    check_figure_path,
    check_seed,
    did_you_mean,
)

__all__ = ["register"]

#: Gymnasium ids without a model ``P`` whose exact model policylab knows (error curves).
KNOWN_MODELS: dict[str, str] = {"Blackjack-v1": "blackjack"}

_TYPES: dict[str, Any] = {
    "flag": bool,
    "float": float,
    "int": int,
    "str": str,
    "schedule": str,
    "policy": str,
}


def _resolve(name: str, gamma: float | None, use_env: bool) -> tuple[Any, Any]:
    """(problem for the learner, exact model or None) from a CLI problem name.

    A built-in problem or a Gymnasium id with a model ``P`` gives a FiniteMDP (the
    compiled path; with ``--env`` its Gymnasium env and the model for scoring); a
    Gymnasium id without ``P`` gives the env (the general path), with policylab's exact
    model where one is known (Blackjack-v1).
    """
    from gymnasium import spaces

    from policylab.cli.common import check_gamma_option, load_problem, make_gym_env
    from policylab.envs import MDPEnv
    from policylab.mdp.finite import FiniteMDP
    from policylab.problems.registry import find_problem, get_problem

    gamma = check_gamma_option(gamma)
    spec = find_problem(name)
    if spec is not None:
        mdp = spec.builder()
        mdp = mdp if gamma is None else mdp.with_gamma(gamma)
        return (MDPEnv(mdp) if use_env else mdp), mdp
    if name in KNOWN_MODELS:
        model = get_problem(KNOWN_MODELS[name])
        model = model if gamma is None else model.with_gamma(gamma)
        env = make_gym_env(name, sab=True) if name == "Blackjack-v1" else make_gym_env(name)
        return env, model
    if "-v" not in name:
        return load_problem(name, gamma), None  # raises UnknownProblemError with the list
    env = make_gym_env(name)
    if getattr(env.unwrapped, "P", None) is not None:
        mdp = FiniteMDP.from_gymnasium(env, gamma=1.0 if gamma is None else gamma, name=name)
        return (env if use_env else mdp), mdp
    space = env.observation_space
    if not isinstance(space, (spaces.Discrete, spaces.Tuple, spaces.MultiDiscrete)):
        raise InvalidArgumentError(
            f"{name} observes {space}; tabular learners need discrete or hashable "
            "observations (Discrete, Tuple of Discrete, MultiDiscrete)"
        )
    return env, None


def _named_policy(problem_name: str, mdp: Any, policy: str | None) -> Any:
    """A problem's registered policy by name, or the uniform policy (None / 'uniform')."""
    from policylab.mdp.policy import Policy
    from policylab.problems.registry import find_problem

    if policy is None or policy == "uniform":
        return None if mdp is None else Policy.uniform(mdp)
    spec = find_problem(problem_name) or find_problem(KNOWN_MODELS.get(problem_name, ""))
    names = sorted(spec.policies) if spec else []
    if spec is None or policy not in spec.policies:
        raise InvalidArgumentError(
            f"unknown policy {policy!r} for {problem_name!r}"
            + did_you_mean(policy, ["uniform", *names])
            + "; known: uniform"
            + (", " + ", ".join(names) if names else "")
        )
    return spec.policies[policy](mdp)


def _show(res: Any, max_rows: int) -> None:
    """Print the learned Q-table, V, the greedy policy and the error curve."""
    console.print(
        f"[bold]{res.algorithm}[/] on [bold]{res.problem}[/]: {res.episodes} episodes, "
        f"{res.steps} steps, {res.seconds:.3g} s ({res.params.get('path')} path)"
    )
    states: list[str] = []
    cells: list[list[str]] = []
    v_col: list[str] = []
    greedy_col: list[str] = []
    for s, lab in enumerate(res.states):
        if res.terminal[s]:
            continue
        if len(states) >= max_rows:
            break
        states.append(fmt_label(lab))
        cells.append(
            [
                f"{res.q[s, a]:.4f}" if res.action_mask[s, a] else "-"
                for a in range(len(res.actions))
            ]
        )
        v_col.append(f"{res.v[s]:.4f}" if res.v is not None else "-")
        greedy_col.append(fmt_label(res.actions[int(np.argmax(res.policy[s]))]))
    for table in state_action_tables(
        "Learned Q(s, a), V(s) and the greedy policy",
        states,
        [f"Q(s, {fmt_label(a)})" for a in res.actions],
        cells,
        {"V(s)": v_col, "greedy": greedy_col},
        console.width,
    ):
        emit_table(table)
    shown = len(states)
    n_live = int((~res.terminal).sum())
    if n_live > shown:
        console.print(f"[dim]... {n_live - shown} more states (raise --max-rows)[/]")
    if res.truncated:
        err_console.print(
            f"[yellow]{res.truncated} episodes hit the step limit and were not used "
            "(raise --max-steps)[/]"
        )
    if res.error is None:
        console.print("[dim]No exact model known: no error against the exact answer.[/]")
        return
    curve = Table(title=f"Error against the exact {res.error_target} as learning goes on")
    for col in ("episodes", "max |error|", "RMS error", "greedy action optimal"):
        curve.add_column(col, justify="right")
    n = len(res.checkpoints)
    for i in sorted(set(np.linspace(0, n - 1, min(n, 10)).round().astype(int))):
        share = res.optimal_actions[i]
        curve.add_row(
            str(res.checkpoints[i]),
            f"{res.error_max[i]:.4g}",
            f"{res.error_rms[i]:.4g}",
            "-" if not np.isfinite(share) else f"{100 * share:.1f}%",
        )
    emit_table(curve)


def _make_command(spec: Any) -> Callable[..., None]:
    """A typer command function for one registered algorithm (signature built from its options)."""

    def command(**kw: Any) -> None:
        from policylab.tabular.schedules import Schedule

        # Every option is checked here, before any work: a bad value (or an output that
        # cannot be written) is refused with its flag's name, not after learning.
        problem_name = kw.pop("problem")
        use_env = kw.pop("env")
        json_out = kw.pop("json_out")
        plot = kw.pop("plot")
        plot = None if plot is None else check_figure_path(plot, "--plot")
        max_rows = check_count(kw.pop("max_rows"), "--max-rows", minimum=0)
        episodes = kw.pop("episodes")
        args: dict[str, Any] = {
            "episodes": check_count(
                spec.default_episodes if episodes is None else episodes,
                "--episodes",
                maximum=MAX_EPISODES,
            ),
            "seed": check_seed(kw.pop("seed"), "--seed"),
            "checkpoints": check_count(kw.pop("checkpoints"), "--checkpoints"),
            "max_steps": check_count(kw.pop("max_steps"), "--max-steps", maximum=MAX_EPISODES),
            "progress": not json_out,
        }
        problem, model = _resolve(problem_name, kw.pop("gamma"), use_env)
        if model is not None and model is not problem:
            args["model"] = model
        if spec.kind == "prediction":
            pol = _named_policy(problem_name, model, kw.pop("policy"))
            if pol is not None:
                args["policy"] = pol
        for opt in spec.options:
            val = kw.pop(opt.param)
            if opt.kind == "flag":
                if val:
                    args[opt.param] = opt.value_if_set
                continue
            if val is None:
                continue
            if opt.kind == "schedule":
                val = Schedule.parse(val)
            elif opt.kind == "policy":
                val = _named_policy(problem_name, model, val)
            args[opt.param] = val
        res = spec.learner(problem, **args)
        if plot is not None:
            from policylab.plot import save_learning_figure

            plot = save_learning_figure(
                res, plot, title=f"{res.algorithm} on {res.problem}: learning curves"
            )
        if json_out:
            print_json(res.to_json())
            return
        _show(res, max_rows)
        if plot is not None:
            console.print(f"figure written to {plot}")

    params = [
        inspect.Parameter(
            "problem",
            inspect.Parameter.KEYWORD_ONLY,
            annotation=Annotated[
                str,
                typer.Argument(
                    help="Problem: a built-in name (slippery-gridworld, blackjack, ...), a "
                    "Gymnasium id with a model P (FrozenLake-v1), or any Gymnasium id with "
                    "discrete or hashable observations (Blackjack-v1; learned by the general "
                    "Python loop).",
                    show_default=False,
                ),
            ],
        ),
        _opt(
            "episodes",
            int | None,
            None,
            "--episodes",
            "-n",
            help=f"Number of episodes (default: {spec.default_episodes}).",
        ),
        _opt(
            "seed",
            int | None,
            None,
            "--seed",
            help="Seed of every random draw; same seed, same result.",
        ),
        _opt(
            "gamma",
            float | None,
            None,
            "--gamma",
            help="Discount rate (default: the problem's own).",
        ),
        _opt(
            "json_out",
            bool,
            False,
            "--json",
            help="Print one JSON object (states, actions, q, v, policy, episodes, steps, "
            "seconds, episode_returns, error) instead of tables.",
        ),
        _opt(
            "plot",
            Path | None,
            None,
            "--plot",
            help="Write the learning figure (error against the exact answer by episode, "
            "return per episode) to this file: PNG, or SVG/PDF by the suffix.",
        ),
        _opt(
            "checkpoints",
            int,
            50,
            "--checkpoints",
            help="About how many points of the error curve (log-spaced).",
        ),
        _opt("max_steps", int, 10_000, "--max-steps", help="Step limit of one episode."),
        _opt(
            "env",
            bool,
            False,
            "--env",
            help="Learn on the problem's Gymnasium env with the plain Python loop "
            "(general path) instead of the compiled kernel.",
        ),
        _opt("max_rows", int, 40, "--max-rows", help="How many states the printed table shows."),
    ]
    if spec.kind == "prediction":
        params.append(
            _opt(
                "policy",
                str | None,
                None,
                "--policy",
                help="Policy to evaluate: 'uniform' (default) or a named policy of the problem "
                "(see `policylab problems`).",
            )
        )
    for opt in spec.options:
        default = False if opt.kind == "flag" else opt.default
        typ = bool if opt.kind == "flag" else _TYPES[opt.kind] | None
        params.append(_opt(opt.param, typ, default, opt.flag, help=opt.help))
    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    command.__annotations__ = {p.name: p.annotation for p in params}
    command.__doc__ = spec.description
    command.__name__ = spec.name.replace("-", "_")
    return command


def _opt(name: str, typ: Any, default: Any, *decls: str, help: str) -> inspect.Parameter:
    return inspect.Parameter(
        name,
        inspect.Parameter.KEYWORD_ONLY,
        default=default,
        annotation=Annotated[typ, typer.Option(*decls, help=help)],
    )


def register(app: typer.Typer) -> None:
    """Add ``policylab learn ALGO PROBLEM`` with one subcommand per registered algorithm."""
    from policylab.tabular.registry import list_algorithms

    learn = typer.Typer(
        name="learn",
        help="Learn from experience with a tabular algorithm (Monte Carlo, TD): prints the learned "
        "table, its error against the exact answer as learning goes on, and a progress bar.",
        no_args_is_help=True,
    )
    for spec in list_algorithms():
        learn.command(spec.name, help=spec.description)(_make_command(spec))
    app.add_typer(learn, name="learn")
