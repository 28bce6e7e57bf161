"""Helpers shared by the command-line subcommands: consoles, problem lookup, JSON."""

from __future__ import annotations

import json
import sys
from typing import Any

from rich.console import Console
from rich.table import Table

from policylab.exceptions import UnknownProblemError
from policylab.mdp.finite import FiniteMDP

__all__ = ["console", "err_console", "fmt_label", "load_problem", "print_json", "values_table"]

console = Console()
err_console = Console(stderr=True)


def fmt_label(x: Any) -> str:
    """A label as written on the command line and in JSON: ``str(label)``."""
    return str(x)


def load_problem(name: str, gamma: float | None = None) -> FiniteMDP:
    """A built-in problem by CLI name, or a Gymnasium id whose env exposes ``P``.

    Raises:
        UnknownProblemError: If neither a built-in problem nor a usable Gymnasium id.
    """
    from policylab.problems.registry import _REGISTRY, get_problem

    key = name.strip().lower().replace("_", "-")
    if key in _REGISTRY:
        mdp = get_problem(key)
    elif "-v" in name:
        import gymnasium as gym

        try:
            env = gym.make(name)
        except Exception as e:  # gymnasium raises its own error types for unknown ids
            raise UnknownProblemError(
                f"unknown problem {name!r} ({type(e).__name__}: {e}); known problems: "
                f"{', '.join(sorted(_REGISTRY))}, or a Gymnasium id with a model `P` "
                "(FrozenLake-v1, CliffWalking-v1, Taxi-v4)"
            ) from None
        mdp = FiniteMDP.from_gymnasium(env, gamma=1.0, name=name)
    else:
        raise UnknownProblemError(
            f"unknown problem {name!r}; known problems: {', '.join(sorted(_REGISTRY))}, "
            "or a Gymnasium id with a model `P` (FrozenLake-v1, CliffWalking-v1, Taxi-v4)"
        )
    return mdp if gamma is None else mdp.with_gamma(gamma)


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
