"""``policylab problems`` and ``policylab show``: the built-in problems and their dynamics."""

from __future__ import annotations

from typing import Annotated

import typer
from rich.table import Table

from policylab.cli.common import (
    console,
    emit_table,
    fmt_label,
    load_problem,
    print_json,
    state_action_tables,
)
from policylab.validation import check_count


def problems_command(
    json_out: Annotated[
        bool, typer.Option("--json", help="Print JSON instead of a table.")
    ] = False,
) -> None:
    """List the built-in problems with a one-line description each."""
    from policylab.problems.registry import list_problems

    specs = list_problems()
    if json_out:
        print_json(
            [
                {
                    "name": s.name,
                    "description": s.description,
                    "gym_id": s.gym_id,
                    "policies": sorted(s.policies),
                }
                for s in specs
            ]
        )
        return
    table = Table(title="Built-in problems (also Gymnasium ids with a model P: FrozenLake-v1, ...)")
    table.add_column("name", style="bold cyan")
    table.add_column("description")
    table.add_column("named policies")
    table.add_column("Gymnasium id", style="dim")
    for s in specs:
        table.add_row(s.name, s.description, ", ".join(sorted(s.policies)) or "-", s.gym_id)
    emit_table(table)


def show_command(
    problem: Annotated[
        str, typer.Argument(help="Problem name (see `policylab problems`) or a Gymnasium id.")
    ],
    max_rows: Annotated[int, typer.Option(help="Show at most this many dynamics rows.")] = 200,
    json_out: Annotated[bool, typer.Option("--json", help="Print JSON instead of tables.")] = False,
) -> None:
    """Show a problem: states, actions, A(s), and its dynamics table p(s', r | s, a)."""
    max_rows = check_count(max_rows, "--max-rows", minimum=0)
    mdp = load_problem(problem)
    if json_out:
        print_json(
            {
                "name": mdp.name,
                "states": [fmt_label(s) for s in mdp.states],
                "actions": [fmt_label(a) for a in mdp.actions],
                "terminal": [
                    fmt_label(s) for s, t in zip(mdp.states, mdp.terminal, strict=True) if t
                ],
                "gamma": mdp.gamma,
                "available_actions": {
                    fmt_label(s): [fmt_label(a) for a in mdp.available_actions(s)]
                    for s in mdp.states
                },
                "dynamics": [
                    {"s": fmt_label(s), "a": fmt_label(a), "p": p, "s_next": fmt_label(n), "r": r}
                    for s in mdp.states
                    for a in mdp.available_actions(s)
                    for p, n, r in mdp.outcomes(s, a)
                ],
            }
        )
        return
    n_term = int(mdp.terminal.sum())
    console.print(
        f"[bold]{mdp.name}[/]: |S+| = {mdp.n_states} states ({n_term} terminal), "
        f"|A| = {mdp.n_actions} actions, {mdp.n_outcomes} outcomes, gamma = {mdp.gamma:g}"
    )
    st = Table(title="States and available actions A(s)")
    st.add_column("state", style="bold")
    st.add_column("kind")
    st.add_column("A(s)")
    st.add_column("P(S0 = s)", justify="right")
    for i, s in enumerate(mdp.states[:max_rows]):
        acts = ", ".join(fmt_label(a) for a in mdp.available_actions(s))
        st.add_row(
            fmt_label(s),
            "terminal" if mdp.terminal[i] else "",
            acts or "-",
            f"{mdp.initial[i]:.3g}",
        )
    emit_table(st)
    dt = Table(title="One-step dynamics p(s', r | s, a)")
    for col in ("s", "a", "s'", "r", "p(s', r | s, a)"):
        dt.add_column(col, justify="right" if col in ("r", "p(s', r | s, a)") else "left")
    shown = 0
    for s in mdp.states:
        for a in mdp.available_actions(s):
            for p, n, r in mdp.outcomes(s, a):
                if shown >= max_rows:
                    break
                dt.add_row(fmt_label(s), fmt_label(a), fmt_label(n), f"{r:g}", f"{p:.4g}")
                shown += 1
    emit_table(dt)
    if mdp.n_outcomes > shown:
        console.print(f"[dim]... {mdp.n_outcomes - shown} more outcomes (raise --max-rows)[/]")
    rsa = mdp.expected_reward
    live = [i for i in range(min(mdp.n_states, max_rows)) if not mdp.terminal[i]]
    for table in state_action_tables(
        "Expected reward r(s, a) = sum p(s', r | s, a) r",
        [fmt_label(mdp.states[i]) for i in live],
        [fmt_label(a) for a in mdp.actions],
        [
            [f"{rsa[i, j]:.4g}" if mdp.action_mask[i, j] else "-" for j in range(mdp.n_actions)]
            for i in live
        ],
        {},
        console.width,
    ):
        emit_table(table)
    if mdp.grid is not None:
        console.print("[bold]Grid[/] (row 0 at the top):")
        for gr in range(mdp.grid.shape[0]):
            cells = []
            for gc in range(mdp.grid.shape[1]):
                idx = mdp.grid.state_at((gr, gc))
                kind = mdp.grid.kinds.get((gr, gc), "")
                cells.append(
                    f"{fmt_label(mdp.states[idx]) if idx is not None else '#'}:{kind}".ljust(18)
                )
            console.print("  " + "".join(cells))
