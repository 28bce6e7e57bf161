"""Helpers shared by the command-line subcommands: consoles, problem lookup, JSON."""

from __future__ import annotations

import json
import sys
from typing import Any

from rich.console import Console
from rich.table import Table

from policylab.exceptions import UnknownProblemError
from policylab.mdp.finite import FiniteMDP
from policylab.problems.registry import find_problem, unknown_problem_message
from policylab.validation import check_gamma

__all__ = [
    "check_gamma_option",
    "console",
    "emit_table",
    "err_console",
    "fmt_label",
    "load_problem",
    "make_gym_env",
    "print_json",
    "state_action_tables",
    "values_table",
]

#: stdout for people; into a pipe long lines are not wrapped (so ``grep`` sees whole lines).
console = Console(soft_wrap=not sys.stdout.isatty())
err_console = Console(stderr=True)


def fmt_label(x: Any) -> str:
    """A label as written on the command line and in JSON: ``str(label)``."""
    return str(x)


GYM_HINT = ", or a Gymnasium id with a model `P` (FrozenLake-v1, CliffWalking-v1, Taxi-v4)"


def make_gym_env(name: str, **kwargs: Any) -> Any:
    """``gymnasium.make(name)``, with Gymnasium's own errors turned into one policylab error.

    Raises:
        UnknownProblemError: An unknown id, or an env whose extra dependency is missing.
    """
    import gymnasium as gym

    try:
        return gym.make(name, **kwargs)
    except Exception as e:  # gymnasium raises its own error types for unknown ids
        detail = " ".join(str(e).split())
        raise UnknownProblemError(
            unknown_problem_message(name, GYM_HINT) + f" (Gymnasium: {detail})"
        ) from None


def check_gamma_option(gamma: float | None) -> float | None:
    """``--gamma``: None (the problem's own) or a number in [0, 1]."""
    return None if gamma is None else check_gamma(gamma, None, "--gamma")


def load_problem(name: str, gamma: float | None = None) -> FiniteMDP:
    """A built-in problem by CLI name, or a Gymnasium id whose env exposes ``P``.

    Raises:
        UnknownProblemError: If neither a built-in problem nor a usable Gymnasium id.
    """
    gamma = check_gamma_option(gamma)
    spec = find_problem(name)
    if spec is not None:
        mdp = spec.builder()
    elif "-v" in name:
        mdp = FiniteMDP.from_gymnasium(make_gym_env(name), gamma=1.0, name=name)
    else:
        raise UnknownProblemError(unknown_problem_message(name, GYM_HINT))
    return mdp if gamma is None else mdp.with_gamma(gamma)


def emit_table(table: Table, out: Console | None = None) -> None:
    """Print a table: boxed on a terminal, plain columns in a pipe or a file.

    Into a pipe (``policylab problems | grep ...``) no cell is ever cut: each row is one
    line of left-aligned columns separated by two spaces, the title on the first line.
    On a terminal a column too narrow for a cell folds it onto more lines rather than
    cutting it with an ellipsis.
    """
    out = out or console
    if out.is_terminal:
        for col in table.columns:
            col.overflow = "fold"
        out.print(table)
        return
    from rich.text import Text

    def plain(x: Any) -> str:
        if isinstance(x, Text):
            return x.plain
        return Text.from_markup(x).plain if isinstance(x, str) else str(x)

    rows = [[plain(c.header) for c in table.columns]]
    cells = [[plain(x) for x in c.cells] for c in table.columns]
    rows += [list(r) for r in zip(*cells, strict=True)]
    widths = [max(len(" ".join(r[i].split())) for r in rows) for i in range(len(rows[0]))]
    lines = [plain(table.title)] if table.title else []
    for r in rows:
        cols = [" ".join(x.split()) for x in r]
        lines.append("  ".join(x.ljust(w) for x, w in zip(cols, widths, strict=True)).rstrip())
    if table.caption:
        lines.append(plain(table.caption))
    out.file.write("\n".join(lines) + "\n")
    out.file.flush()


def state_action_tables(
    title: str,
    states: list[str],
    headers: list[str],
    cells: list[list[str]],
    extra: dict[str, list[str]],
    width: int,
) -> list[Table]:
    """A per-state, per-action table (Q(s, a), r(s, a)) as tables that fit ``width`` columns.

    One row per state (a column per action, then the ``extra`` per-state columns) when
    that fits; else transposed, one row per action, when there are fewer states than
    actions and that fits; else the actions split into groups of columns, one table each.

    Args:
        title: Title of the table.
        states: Row labels, one per state shown.
        headers: Column headers, one per action.
        cells: ``cells[i][j]``: the text for state ``i`` and action ``j``.
        extra: Further per-state columns (``V(s)``, the greedy action), by header.
        width: The terminal's width.
    """

    def need(first: list[str], cols: list[list[str]]) -> int:
        return (
            max(len(x) for x in ["state", *first])
            + 4
            + sum(max(len(x) for x in col) + 3 for col in cols)
        )

    def one_row_per_state(name: str, group: Any) -> Table:
        table = Table(title=name)
        table.add_column("state", style="bold")
        for j in group:
            table.add_column(headers[j], justify="right")
        for h in extra:
            table.add_column(h, justify="right" if h != "greedy" else "left")
        for i, st in enumerate(states):
            table.add_row(st, *(cells[i][j] for j in group), *(col[i] for col in extra.values()))
        return table

    cols = [[h, *(row[j] for row in cells)] for j, h in enumerate(headers)]
    tail = [[h, *col] for h, col in extra.items()]
    if not states or need(states, cols + tail) <= width:
        return [one_row_per_state(title, range(len(headers)))]
    t_cols = [[st, *cells[i], *(col[i] for col in extra.values())] for i, st in enumerate(states)]
    if len(states) < len(headers) and need([*headers, *extra], t_cols) <= width:
        table = Table(title=title + " (one row per action)")
        table.add_column("", style="bold")
        for st in states:
            table.add_column(st, justify="right")
        for j, h in enumerate(headers):
            table.add_row(h, *(row[j] for row in cells))
        for h, col in extra.items():
            table.add_row(h, *col)
        return [table]
    groups: list[list[int]] = [[]]
    for j in range(len(headers)):
        if groups[-1] and need(states, [cols[k] for k in [*groups[-1], j]] + tail) > width:
            groups.append([])
        groups[-1].append(j)
    return [
        one_row_per_state(
            f"{title} (part {i + 1} of {len(groups)}: actions {g[0] + 1}-{g[-1] + 1} of "
            f"{len(headers)})",
            g,
        )
        for i, g in enumerate(groups)
    ]


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout (no rich markup)."""
    sys.stdout.write(json.dumps(obj) + "\n")
    sys.stdout.flush()


def values_table(title: str, mdp: FiniteMDP, columns: dict[str, Any]) -> Table:
    """A rich table with one row per state and the given per-state columns."""
    table = Table(title=title)
    table.add_column("state", style="bold")
    for name in columns:
        table.add_column(name, justify="right")
    for s, lab in enumerate(mdp.states):
        row = []
        for col in columns.values():
            v = col[s]
            row.append(f"{v:.4f}" if isinstance(v, float) else str(v))
        table.add_row(fmt_label(lab), *row)
    return table
