"""``policylab solve`` and ``policylab evaluate``: exact planning from the command line."""

from __future__ import annotations

import json
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.table import Table

from policylab.cli.common import console, emit_table, fmt_label, load_problem, print_json
from policylab.exceptions import InvalidArgumentError, InvalidPolicyError
from policylab.validation import (
    check_choice,
    check_count,
    check_figure_path,
    check_positive,
    did_you_mean,
)

if TYPE_CHECKING:
    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy
    from policylab.planning.result import PlanningResult

__all__ = ["evaluate_command", "load_policy", "register", "solve_command"]


METHOD_NAMES = {
    "auto": "the method that suits the problem",
    "vi": "value iteration",
    "vi-gs": "value iteration (Gauss-Seidel, terminal states first)",
    "pi": "policy iteration",
    "mpi": "modified policy iteration (adaptive m)",
    "lp": "linear programming (HiGHS)",
}

ProblemArg = Annotated[
    str,
    typer.Argument(
        help="A built-in problem (see `policylab problems`, e.g. gridworld-5x5, "
        "jacks-car-rental) or a Gymnasium id with a model P (FrozenLake-v1)."
    ),
]
GammaOpt = Annotated[
    float | None,
    typer.Option("--gamma", help="Discount rate in [0, 1]; default: the problem's own."),
]
JsonOpt = Annotated[
    bool,
    typer.Option(
        "--json", help="Print one JSON object (states, actions, v, policy) instead of tables."
    ),
]
PlotOpt = Annotated[
    Path | None,
    typer.Option(
        "--plot",
        help="Also save a figure of the values and the policy to this file (PNG, PDF, SVG).",
    ),
]
RowsOpt = Annotated[
    int, typer.Option("--max-rows", help="Show at most this many states in the table.")
]


def solve_command(
    problem: ProblemArg,
    method: Annotated[
        str,
        typer.Option(
            "--method",
            help="auto (default): chosen from the problem's size, gamma and structure, "
            "reported with the reason; vi: value iteration (MacQueen's stopping bound); "
            "vi-gs: in-place sweeps from the terminal states backwards; pi: policy "
            "iteration (exact evaluation); mpi: modified policy iteration (adaptive m); lp: "
            "linear programming with HiGHS.",
        ),
    ] = "auto",
    gamma: GammaOpt = None,
    tol: Annotated[
        float,
        typer.Option(
            "--tol", help="vi/mpi: the returned values are within tol of v_* (gamma < 1)."
        ),
    ] = 1e-8,
    json_out: JsonOpt = False,
    plot: PlotOpt = None,
    max_rows: RowsOpt = 60,
    position: Annotated[
        str | None,
        typer.Option(
            "--position",
            help="tic-tac-toe / connect-four only: the moves played (cells 1-9 or columns "
            "1-7), e.g. 4455.",
        ),
    ] = None,
) -> None:
    """Solve a problem exactly: optimal values v_* and an optimal policy pi_*.

    Board games: `solve tic-tac-toe [--position MOVES]` gives the value and optimal moves,
    `solve connect-four --position MOVES` the score in Pascal Pons' convention.
    """
    from policylab.games.registry import is_game

    if is_game(problem):
        from policylab.cli.cmd_games import solve_game

        return solve_game(problem, position, json_out)
    if position is not None:
        raise InvalidArgumentError(
            f"--position is for the board games (tic-tac-toe, connect-four); {problem!r} is not one"
        )
    from policylab.planning import solve

    plot, tol = _check_outputs(plot, max_rows), check_positive(tol, "--tol")
    mdp = load_problem(problem, gamma)
    m = _choice(method, tuple(METHOD_NAMES), "--method")
    with (
        console.status(f"solving {mdp.name} by {METHOD_NAMES[m]} ...", spinner="dots")
        if not json_out
        else nullcontext()
    ):
        res = solve(mdp, m, tol=tol)
    if json_out:
        print_json({**_payload(mdp, res.v, res.policy), "iterations": int(res.iterations)})
    else:
        _print_summary(mdp, res)
        emit_table(
            _solution_table(mdp, res.v, res.policy, f"v_* and pi_* of {mdp.name}", max_rows, res)
        )
    if plot is not None:
        _plot(
            mdp,
            res.v,
            res.policy,
            plot,
            f"{mdp.name}: optimal values and policy ({res.method})",
            json_out=json_out,
            ties=True,
        )


def evaluate_command(
    problem: ProblemArg,
    policy: Annotated[
        str,
        typer.Option(
            "--policy",
            help="'uniform' (equiprobable random), a named policy of the problem (see "
            "`policylab problems`), or a JSON file {state: {action: prob}} with labels "
            "written by str().",
        ),
    ],
    method: Annotated[
        str,
        typer.Option("--method", help="exact: sparse linear solve; iterative: Bellman sweeps."),
    ] = "exact",
    gamma: GammaOpt = None,
    json_out: JsonOpt = False,
    plot: PlotOpt = None,
    max_rows: RowsOpt = 60,
) -> None:
    """Evaluate a policy exactly: v_pi from the Bellman expectation equation."""
    from policylab.planning import evaluate_policy

    how = _choice(method, ("exact", "iterative"), "--method")
    plot = _check_outputs(plot, max_rows)
    mdp = load_problem(problem, gamma)
    pi = load_policy(mdp, problem, policy)
    res = evaluate_policy(mdp, pi, method=how, return_result=True)
    if json_out:
        print_json(_payload(mdp, res.v, pi))
    else:
        _print_summary(mdp, res)
        emit_table(
            _solution_table(
                mdp, res.v, pi, f"v_pi of policy {policy!r} on {mdp.name}", max_rows, res
            )
        )
    if plot is not None:
        _plot(mdp, res.v, pi, plot, f"{mdp.name}: values of policy {policy}", json_out=json_out)


def load_policy(mdp: FiniteMDP, problem: str, spec: str) -> Policy:
    """A policy by name ('uniform', a registered one) or from a JSON file of str labels.

    Raises:
        InvalidPolicyError: Unknown name, unreadable file, or labels the MDP lacks.
    """
    from policylab.mdp.policy import Policy
    from policylab.problems.registry import find_problem

    if spec == "uniform":
        return Policy.uniform(mdp)
    found = find_problem(problem)
    named = found.policies if found is not None else {}
    if spec in named:
        return named[spec](mdp)
    path = Path(spec)
    if path.suffix != ".json":
        known = ", ".join(["uniform", *sorted(named)])
        raise InvalidPolicyError(
            f"unknown policy {spec!r} for {problem!r}{did_you_mean(spec, ['uniform', *named])}; "
            f"known policies: {known}, or a FILE.json"
        )
    try:
        table = json.loads(path.read_text())
    except FileNotFoundError:
        raise InvalidPolicyError(f"policy file {str(path)!r} does not exist") from None
    except (OSError, ValueError) as e:
        raise InvalidPolicyError(f"policy file {str(path)!r} is not valid JSON: {e}") from None
    if not isinstance(table, dict):
        raise InvalidPolicyError(
            f"policy file {str(path)!r} must hold an object {{state: {{action: prob}}}}; "
            f"got {type(table).__name__}"
        )
    states = {fmt_label(s): s for s in mdp.states}
    actions = {fmt_label(a): a for a in mdp.actions}
    mapping: dict[Any, dict[Any, float]] = {}
    for s_str, row in table.items():
        if s_str not in states:
            raise InvalidPolicyError(
                f"policy file {str(path)!r} names state {s_str!r}, which {mdp.name} does not have"
            )
        if not isinstance(row, dict):
            raise InvalidPolicyError(
                f"policy file {str(path)!r}: the entry of state {s_str!r} must be "
                f"{{action: prob}}; got {row!r}"
            )
        out: dict[Any, float] = {}
        for a_str, p in row.items():
            if a_str not in actions:
                raise InvalidPolicyError(
                    f"policy file {str(path)!r}: state {s_str!r} names action {a_str!r}, which "
                    f"{mdp.name} does not have; actions are {list(actions)}"
                )
            out[actions[a_str]] = p
        mapping[states[s_str]] = out
    return Policy.stochastic(mdp, mapping)


def _check_outputs(plot: Path | None, max_rows: int) -> Path | None:
    """``--plot`` (the figure's path, writable, known suffix) and ``--max-rows``, before work."""
    check_count(max_rows, "--max-rows", minimum=0)
    return None if plot is None else check_figure_path(plot, "--plot")


def _choice(value: str, allowed: tuple[str, ...], option: str) -> str:
    """Check a choice option here, so that a bad value exits with code 2 and one line."""
    return check_choice(value, allowed, option)


def _payload(mdp: FiniteMDP, v: np.ndarray, pi: Policy) -> dict[str, Any]:
    return {
        "states": [fmt_label(s) for s in mdp.states],
        "actions": [fmt_label(a) for a in mdp.actions],
        "v": [float(x) for x in v],
        "policy": pi.to_dict(),
    }


def _print_summary(mdp: FiniteMDP, res: PlanningResult) -> None:
    bound = "none (gamma = 1)" if res.error_bound is None else f"{res.error_bound:.2g}"
    state = "[green]converged[/]" if res.converged else "[red]NOT converged[/]"
    console.print(
        f"[bold]{mdp.name}[/]: {mdp.n_states} states, {mdp.n_actions} actions, gamma = "
        f"{res.gamma:g}. {res.method}: {state} in {res.iterations} iterations, "
        f"{res.seconds:.3g} s; error bound on v: {bound}"
    )
    if "auto" in res.info:
        auto = res.info["auto"]
        console.print(f"method auto chose {auto['method']}: {auto['reason']}")


def _solution_table(
    mdp: FiniteMDP, v: np.ndarray, pi: Policy, title: str, max_rows: int, res: PlanningResult
) -> Table:
    table = Table(title=title)
    table.add_column("state", style="bold")
    table.add_column("v", justify="right")
    table.add_column("policy pi(a|s)")
    table.add_column("greedy actions (ties)")
    from policylab.planning import optimal_actions

    best = optimal_actions(mdp, np.where(mdp.action_mask, res.q, 0.0), 1e-9)
    probs = pi.probs
    for s in range(min(mdp.n_states, max(0, max_rows))):
        if mdp.terminal[s]:
            table.add_row(fmt_label(mdp.states[s]), f"{v[s]:.4f}", "[dim]terminal[/]", "")
            continue
        acts = np.flatnonzero(probs[s])
        pol = ", ".join(
            fmt_label(mdp.actions[a]) + ("" if probs[s, a] == 1 else f" {probs[s, a]:.3g}")
            for a in acts
        )
        ties = ", ".join(fmt_label(mdp.actions[a]) for a in np.flatnonzero(best[s]))
        table.add_row(fmt_label(mdp.states[s]), f"{v[s]:.4f}", pol, ties)
    if mdp.n_states > max_rows:
        table.caption = f"{mdp.n_states - max_rows} more states (raise --max-rows, or use --json)"
    return table


def _plot(
    mdp: FiniteMDP,
    v: np.ndarray,
    pi: Policy,
    path: Path,
    title: str,
    *,
    json_out: bool,
    ties: bool = False,
) -> None:
    """Save the figure that fits the problem (values, policy, q) for ``--plot``.

    ``ties``: v is v_*, so a gridworld's policy panel draws every optimal action.
    """
    from policylab.planning import action_values
    from policylab.plot import save_solution_figure

    written = save_solution_figure(
        mdp, v, pi, path, title=title, q=action_values(mdp, v), ties=ties
    )
    if not json_out:  # stdout holds exactly one JSON object with --json
        console.print(f"figure written to {written}")


def register(app: typer.Typer) -> None:
    """Add ``solve`` and ``evaluate`` to the ``policylab`` command."""
    app.command("solve")(solve_command)
    app.command("evaluate")(evaluate_command)
