"""`policylab solve` and `policylab evaluate`: tables, the JSON contract, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from policylab.cli.main import main


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as e:
        main([*args])
        raise SystemExit(0)
    out = capsys.readouterr()
    return int(e.value.code or 0), out.out, out.err


@pytest.mark.parametrize("method", ["auto", "vi", "vi-gs", "pi", "mpi", "lp"])
def test_solve_json_contract(capsys: pytest.CaptureFixture[str], method: str) -> None:
    code, out, _ = run(capsys, "solve", "recycling-robot", "--method", method, "--json")
    assert code == 0
    data = json.loads(out)
    assert set(data) == {"states", "actions", "v", "policy", "iterations"}
    assert data["states"] == ["high", "low"]
    assert data["actions"] == ["search", "wait", "recharge"]
    assert data["v"] == pytest.approx([31.496063, 28.346457], abs=1e-5)
    assert data["policy"] == {"high": {"search": 1.0}, "low": {"recharge": 1.0}}
    assert isinstance(data["iterations"], int)


def test_solve_defaults_to_auto_and_says_what_it_chose(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = run(capsys, "solve", "gridworld-4x4")
    assert code == 0
    assert "auto chose pi" in " ".join(out.split())
    assert "episodic task with gamma = 1" in " ".join(out.split())
    code, out, _ = run(capsys, "solve", "slip-gridworld", "--json")
    # 98 successful moves from the corner; each costs 1 / (1 - 0.1 g) in expectation
    # and carries the discount b = 0.9 g / (1 - 0.1 g).
    g = 0.99
    b = 0.9 * g / (1 - 0.1 * g)
    want = -(1 - b**98) / (1 - b) / (1 - 0.1 * g)
    assert code == 0 and json.loads(out)["v"][0] == pytest.approx(want, abs=1e-6)


def test_solve_tables_gamma_and_gym_ids(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "solve", "gridworld-5x5", "--method", "vi", "--tol", "1e-6")
    assert code == 0 and "24.4" in out and "converged" in out
    code, out, _ = run(capsys, "solve", "FrozenLake-v1", "--json")
    assert code == 0 and json.loads(out)["v"][0] == pytest.approx(14 / 17)
    code, out, _ = run(capsys, "solve", "recycling-robot", "--gamma", "0.5", "--json")
    v = json.loads(out)["v"]
    code, out2, _ = run(capsys, "solve", "recycling-robot", "--json")
    assert v != json.loads(out2)["v"]


def test_evaluate_named_uniform_and_file(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, out, _ = run(capsys, "evaluate", "mountain-gridworld", "--policy", "bad", "--json")
    data = json.loads(out)
    assert code == 0 and set(data) == {"states", "actions", "v", "policy"}
    v = dict(zip(data["states"], data["v"], strict=True))
    assert v["(2, 0)"] == pytest.approx(-6) and v["(2, 1)"] == pytest.approx(-5)
    code, out, _ = run(capsys, "evaluate", "gridworld-4x4", "--policy", "uniform")
    assert code == 0 and "-22.0000" in out
    f = tmp_path / "pi.json"
    f.write_text(json.dumps({"high": {"search": 1}, "low": {"recharge": 0.5, "wait": 0.5}}))
    code, out, _ = run(capsys, "evaluate", "recycling-robot", "--policy", str(f), "--json")
    assert code == 0 and json.loads(out)["policy"]["low"] == {"wait": 0.5, "recharge": 0.5}
    code, out, _ = run(
        capsys, "evaluate", "recycling-robot", "--policy", "stochastic", "--method", "iterative"
    )
    assert code == 0 and "28.6188" in out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("solve", "no-such-problem"), "unknown problem"),
        (("solve", "recycling-robot", "--method", "magic"), "--method must be one of"),
        (("solve", "recycling-robot", "--gamma", "2"), "gamma"),
        (("solve", "recycling-robot", "--method", "vi", "--tol", "-1"), "tol"),
        (("evaluate", "recycling-robot", "--policy", "nope"), "unknown policy 'nope'"),
        (("evaluate", "recycling-robot", "--policy", "missing.json"), "does not exist"),
        (("evaluate", "recycling-robot", "--policy", "uniform", "--gamma", "1"), "'high'"),
        (("evaluate", "recycling-robot", "--policy", "uniform", "--method", "x"), "--method"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    capsys: pytest.CaptureFixture[str], args: tuple[str, ...], message: str
) -> None:
    code, _, err = run(capsys, *args)
    assert code == 2
    assert message in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_bad_policy_files(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    cases = {
        "bad.json": ("{not json", "not valid JSON"),
        "state.json": (json.dumps({"medium": {"search": 1}}), "state 'medium'"),
        "action.json": (json.dumps({"high": {"fly": 1}, "low": {"wait": 1}}), "action 'fly'"),
        "sum.json": (json.dumps({"high": {"search": 0.5}, "low": {"wait": 1}}), "sums to 0.5"),
        "list.json": (json.dumps([1, 2]), "must hold an object"),
    }
    for name, (text, message) in cases.items():
        f = tmp_path / name
        f.write_text(text)
        code, _, err = run(capsys, "evaluate", "recycling-robot", "--policy", str(f))
        assert code == 2, name
        assert message in err, (name, err)


def test_tour_sections_run(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    from policylab.cli.common import console
    from policylab.cli.tour import TourContext, sections

    ctx = TourContext(console=console, out_dir=tmp_path, quick=True)
    mine = [(o, t, f) for o, t, f in sections() if f.__module__ == "policylab.cli.tour_planning"]
    assert len(mine) == 3
    for _, _, fn in mine:
        fn(ctx)
    out = capsys.readouterr().out
    assert "better" in out and "-6" in out and "-5" in out and "v_*(start) = 4" in out
