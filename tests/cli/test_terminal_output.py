"""Output that fits a terminal and a pipe: no cut identifiers, tables within 80 columns."""

from __future__ import annotations

import io
import json
from collections.abc import Callable

import pytest
from rich.console import Console

from policylab.cli.common import emit_table, state_action_tables

RunCLI = Callable[[list[str]], tuple[int, str, str]]  # the run_cli fixture (conftest.py)


def test_problems_in_a_pipe_never_cut_an_identifier(run_cli: RunCLI) -> None:
    code, out, _ = run_cli(["problems"])
    assert code == 0 and "…" not in out
    code, js, _ = run_cli(["problems", "--json"])
    lines = out.splitlines()
    for p in json.loads(js):
        # one line per problem holds its whole name and its whole Gymnasium id
        row = [ln for ln in lines if ln.startswith(p["name"] + " ")]
        assert len(row) == 1 and p["gym_id"] in row[0], p["name"]


def _render(tables: list, width: int) -> list[str]:
    buf = io.StringIO()
    con = Console(file=buf, width=width, force_terminal=True, color_system=None)
    for t in tables:
        emit_table(t, con)
    return buf.getvalue().splitlines()


def test_a_table_on_a_narrow_terminal_folds_cells_instead_of_cutting_them() -> None:
    from rich.table import Table

    t = Table()
    t.add_column("name")
    t.add_column("id")
    t.add_row("mountain-gridworld", "policylab/MountainGridworld-v0")
    lines = _render([t], 24)
    assert "…" not in "".join(lines)
    body = [ln.split("│") for ln in lines if ln.startswith("│")]
    assert "".join(c[1].strip() for c in body) == "mountain-gridworld"
    assert "".join(c[2].strip() for c in body) == "policylab/MountainGridworld-v0"


@pytest.mark.parametrize(("n_states", "n_actions"), [(2, 12), (40, 12), (3, 4), (60, 30)])
def test_q_tables_fit_80_columns(n_states: int, n_actions: int) -> None:
    actions = [f"b{j}" for j in range(n_actions)]
    tables = state_action_tables(
        "Q",
        [f"s{s}" for s in range(n_states)],
        [f"Q(s, {a})" for a in actions],
        [["-0.1234"] * n_actions for _ in range(n_states)],
        {"V(s)": ["0.5000"] * n_states, "greedy": ["b0"] * n_states},
        80,
    )
    lines = _render(tables, 80)
    assert max(len(ln) for ln in lines) <= 80
    assert "…" not in "\n".join(lines)
    text = "\n".join(lines)
    for a in actions:  # every action's column (or row) is shown somewhere
        assert f"Q(s, {a})" in text


def test_wide_q_table_of_maximization_bias_is_transposed(
    run_cli: RunCLI,
) -> None:
    code, out, _ = run_cli(
        ["learn", "double-q-learning", "maximization-bias", "-n", "50", "--seed", "0"]
    )
    assert code == 0 and "one row per action" in out
    assert max(len(ln) for ln in out.splitlines()) <= 100


@pytest.mark.parametrize("unit", ["episodes", None])
def test_progress_bar_keeps_its_time_columns_at_80_columns(unit: str | None) -> None:
    from rich.progress import Progress

    from policylab.tabular.common import progress_columns

    buf = io.StringIO()
    con = Console(file=buf, width=80, force_terminal=True, color_system=None)
    prog = Progress(*progress_columns(unit), console=con, expand=True)
    task = prog.add_task("sarsa-lambda on mountain-gridworld, 10 seeds", total=10_000_000)
    prog.advance(task, 1_234_567)
    con.print(prog.make_tasks_table(prog.tasks))
    line = buf.getvalue().splitlines()[0]
    assert len(line) <= 80, line
    assert line.rstrip().endswith("-:--:--"), line  # the remaining time, whole
    assert ("1234567/10000000 episodes" if unit else "12%") in line


def test_show_transposes_a_wide_expected_reward_table(run_cli: RunCLI) -> None:
    code, out, _ = run_cli(["show", "maximization-bias", "--max-rows", "3"])
    assert code == 0 and "r(s, a) = sum p(s', r | s, a) r (one row per action)" in out
