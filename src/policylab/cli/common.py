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
    "console",
    "err_console",
    "fmt_label",
    "load_problem",
    "make_gym_env",
    "print_json",
    "values_table",
]

console = Console()
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


def load_problem(name: str, gamma: float | None = None) -> FiniteMDP:
    """A built-in problem by CLI name, or a Gymnasium id whose env exposes ``P``.

    Raises:
        UnknownProblemError: If neither a built-in problem nor a usable Gymnasium id.
    """
    gamma = check_gamma(gamma, 1.0) if gamma is not None else None
    spec = find_problem(name)
    if spec is not None:
        mdp = spec.builder()
    elif "-v" in name:
        mdp = FiniteMDP.from_gymnasium(make_gym_env(name), gamma=1.0, name=name)
    else:
        raise UnknownProblemError(unknown_problem_message(name, GYM_HINT))
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
