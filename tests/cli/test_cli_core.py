"""The command line: problems, show, tour, and exit codes."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from policylab.cli.main import main


def run(args, capsys):
    with pytest.raises(SystemExit) as exc:
        main([*args])
        raise SystemExit(0)
    out = capsys.readouterr()
    return exc.value.code or 0, out.out, out.err


def test_problems_json(capsys):
    code, out, _ = run(["problems", "--json"], capsys)
    assert code == 0
    names = {p["name"] for p in json.loads(out)}
    assert "recycling-robot" in names


def test_show_prints_dynamics(capsys):
    code, out, _ = run(["show", "recycling-robot"], capsys)
    assert code == 0 and "p(s', r | s, a)" in out and "recharge" in out
    code, out, _ = run(["show", "slippery-gridworld", "--json"], capsys)
    data = json.loads(out)
    assert data["terminal"] == ["4"] and data["available_actions"]["1"] == [
        "up",
        "down",
        "left",
        "right",
    ]


def test_show_gymnasium_id(capsys):
    code, out, _ = run(["show", "FrozenLake-v1", "--json"], capsys)
    assert code == 0 and len(json.loads(out)["states"]) == 16


def test_unknown_problem_exit_code_2_with_names():
    proc = subprocess.run(
        [sys.executable, "-m", "policylab", "show", "no-such-problem"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert "unknown problem 'no-such-problem'" in proc.stderr and "recycling-robot" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_unknown_gym_id_exit_code_2():
    proc = subprocess.run(
        [sys.executable, "-m", "policylab", "show", "NoSuchEnv-v9"], capture_output=True, text=True
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


def test_help_on_every_subcommand(capsys):
    from policylab.cli.main import app

    for cmd in app.registered_commands:
        name = cmd.name or cmd.callback.__name__
        code, out, _ = run([name, "--help"], capsys)
        assert code == 0 and "Usage" in out, name


@pytest.mark.parametrize(
    "args", [["evaluate", "recycling-robot"], ["solve"], ["no-such-command"], ["show", "--bogus"]]
)
def test_usage_errors_exit_2_without_traceback(args):
    proc = subprocess.run(
        [sys.executable, "-m", "policylab", *args], capture_output=True, text=True
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and proc.stderr.startswith("policylab: error:")
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
