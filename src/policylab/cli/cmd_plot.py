"""``policylab plot ...``: figures of a problem's values, policies and Q-table from the shell.

matplotlib is imported only when a figure is drawn, so ``policylab --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from policylab.cli.common import console
from policylab.validation import check_figure_path

__all__ = ["register"]

_PROBLEM_HELP = (
    "Problem: a built-in name (mountain-gridworld, recycling-robot, ...; see `policylab "
    "problems`) or a Gymnasium id with a model P (FrozenLake-v1, CliffWalking-v1)."
)
_OUT_HELP = (
    "Where to write the figure: PNG by default, SVG or PDF by the suffix "
    "(default: runs/plots/PROBLEM-KIND.png)."
)

plot_app = typer.Typer(
    name="plot",
    help=(
        "Draw figures: state values as heatmaps or bars, policies as arrows or maps, the "
        "Q-table as triangles (notes' figure 9). The figure is chosen by the problem: "
        "gridworlds, small problems, 1-D problems (gambler), 2-D state spaces (car "
        "rental), Blackjack."
    ),
    no_args_is_help=True,
)


def _out_path(out: Path | None, problem: str, kind: str) -> Path:
    """The figure's path (``--out`` or the default), checked before anything is drawn."""
    if out is None:
        safe = problem.replace("/", "_")
        out = Path("runs") / "plots" / f"{safe}-{kind}.png"
    return check_figure_path(out, "--out")


@plot_app.command("values")
def values_command(
    problem: Annotated[str, typer.Argument(help=_PROBLEM_HELP)],
    policy: Annotated[
        str,
        typer.Option(
            "--policy",
            "-p",
            help="The policy to evaluate: 'uniform' (equiprobable random), a named policy "
            "of the problem (see `policylab problems`), or a JSON file {state: {action: "
            "prob}} with labels written by str().",
        ),
    ] = "uniform",
    out: Annotated[Path | None, typer.Option("--out", "-o", help=_OUT_HELP)] = None,
    gamma: Annotated[
        float | None, typer.Option(help="Discount rate in [0, 1] (default: the problem's).")
    ] = None,
    q: Annotated[
        bool,
        typer.Option(
            "--q/--no-q",
            help="Also draw q_pi(s, a) where the figure has a view for it.",
        ),
    ] = True,
    title: Annotated[str | None, typer.Option(help="Figure title.")] = None,
) -> None:
    """Draw v_pi of a policy (exact, by a linear solve) with the policy itself."""
    from policylab.cli.cmd_planning import load_policy
    from policylab.cli.common import load_problem
    from policylab.planning import action_values, evaluate_policy
    from policylab.plot import save_solution_figure

    target = _out_path(out, problem, f"{policy}-values")
    mdp = load_problem(problem, gamma)
    pi = load_policy(mdp, problem, policy)
    v = evaluate_policy(mdp, pi)
    qv = action_values(mdp, v) if q else None
    path = save_solution_figure(
        mdp,
        v,
        pi,
        target,
        q=qv,
        title=title or f"Policy '{policy}' and its values — {mdp.name} (γ = {mdp.gamma:g})",
    )
    console.print(f"wrote {path}")


@plot_app.command("optimal")
def optimal_command(
    problem: Annotated[str, typer.Argument(help=_PROBLEM_HELP)],
    out: Annotated[Path | None, typer.Option("--out", "-o", help=_OUT_HELP)] = None,
    gamma: Annotated[
        float | None, typer.Option(help="Discount rate in [0, 1] (default: the problem's).")
    ] = None,
    q: Annotated[
        bool,
        typer.Option(
            "--q/--no-q",
            help="Also draw q*(s, a) where the figure has a view for it.",
        ),
    ] = True,
    title: Annotated[str | None, typer.Option(help="Figure title.")] = None,
) -> None:
    """Solve the problem exactly (value iteration) and draw v*, an optimal policy and q*.

    On a gridworld, every optimal action of a state gets an arrow (as in Figure 3.5).
    """
    from policylab.cli.common import load_problem
    from policylab.planning import value_iteration
    from policylab.plot import save_solution_figure

    target = _out_path(out, problem, "optimal")
    mdp = load_problem(problem, gamma)
    res = value_iteration(mdp)
    path = save_solution_figure(
        mdp,
        res.v,
        res.policy,
        target,
        q=res.q if q else None,
        title=title or f"Optimal values v* and policy π* — {mdp.name} (γ = {mdp.gamma:g})",
        ties=True,
    )
    console.print(f"wrote {path}")


@plot_app.command("q-table")
def q_table_command(
    problem: Annotated[str, typer.Argument(help=_PROBLEM_HELP)],
    policy: Annotated[
        str,
        typer.Option(
            "--policy",
            "-p",
            help="'optimal' draws q*; else q_pi of this policy ('uniform', a named policy "
            "of the problem, or a JSON file {state: {action: prob}}).",
        ),
    ] = "optimal",
    out: Annotated[Path | None, typer.Option("--out", "-o", help=_OUT_HELP)] = None,
    gamma: Annotated[
        float | None, typer.Option(help="Discount rate in [0, 1] (default: the problem's).")
    ] = None,
) -> None:
    """Draw the Q-table of a gridworld as four triangles per cell (the notes' figure 9)."""
    from policylab.cli.cmd_planning import load_policy
    from policylab.cli.common import load_problem
    from policylab.planning import action_values, evaluate_policy, value_iteration
    from policylab.plot import q_table_figure, save_figure
    from policylab.plot.grid import q_triangles, require_grid

    target = _out_path(out, problem, f"{policy}-q-table")
    mdp = load_problem(problem, gamma)
    q_triangles(require_grid(mdp, "the Q-table view"), mdp)  # refused before solving
    if policy.strip().lower() == "optimal":
        qv = value_iteration(mdp).q
        what = "q*"
    else:
        qv = action_values(mdp, evaluate_policy(mdp, load_policy(mdp, problem, policy)))
        what = f"q of policy '{policy}'"
    fig = q_table_figure(
        mdp, qv, title=f"Q-table: {what} — {mdp.name} (γ = {mdp.gamma:g}; bold: greedy action)"
    )
    path = save_figure(fig, target)
    console.print(f"wrote {path}")


def register(app: typer.Typer) -> None:
    """Add ``policylab plot`` to the command line."""
    app.add_typer(plot_app, name="plot")
