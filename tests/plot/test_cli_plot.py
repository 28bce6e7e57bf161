"""`policylab plot ...` and the `--plot` options of solve, evaluate and learn."""

from __future__ import annotations

import json

import pytest

from policylab.cli.main import main

PNG = b"\x89PNG\r\n\x1a\n"


def run(capsys, *args: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as e:
        main([*args])
        raise SystemExit(0)
    out = capsys.readouterr()
    return int(e.value.code or 0), out.out, out.err


def test_plot_optimal_values_and_q_table(capsys, tmp_path):
    code, out, _ = run(
        capsys, "plot", "optimal", "mountain-gridworld", "--out", str(tmp_path / "o.png")
    )
    assert code == 0 and "o.png" in out
    assert (tmp_path / "o.png").read_bytes()[:8] == PNG
    svg = tmp_path / "robot.svg"
    code, _, _ = run(
        capsys, "plot", "values", "recycling-robot", "-p", "stochastic", "-o", str(svg)
    )
    assert code == 0 and "<svg" in svg.read_text()
    code, _, _ = run(
        capsys,
        "plot",
        "q-table",
        "slippery-gridworld",
        "-p",
        "uniform",
        "-o",
        str(tmp_path / "q.png"),
    )
    assert code == 0 and (tmp_path / "q.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["plot", "values", "mountain-gridworld", "-p", "nope"], "nope"),
        (["plot", "q-table", "recycling-robot"], "grid-shaped"),
        (["plot", "optimal", "random-mdp"], "no solution figure fits"),
        (["plot", "optimal", "mountain-gridworld", "-o", "x.jpg"], "'.jpg'"),
    ],
)
def test_plot_refusals_exit_2_with_one_line(capsys, tmp_path, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *args)
    assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "x.jpg").exists()


def test_solve_and_evaluate_plot_keep_json_clean(capsys, tmp_path):
    code, out, _ = run(
        capsys, "solve", "gridworld-4x4", "--json", "--plot", str(tmp_path / "s.png")
    )
    assert code == 0 and json.loads(out)["v"][1] == pytest.approx(-1.0)
    assert (tmp_path / "s.png").read_bytes()[:8] == PNG
    code, out, _ = run(
        capsys,
        "evaluate",
        "mountain-gridworld",
        "--policy",
        "bad",
        "--plot",
        str(tmp_path / "e.svg"),
    )
    assert code == 0 and "e.svg" in out and (tmp_path / "e.svg").stat().st_size > 0


def test_learn_plot_writes_the_learning_figure(capsys, tmp_path):
    path = tmp_path / "learn.png"
    code, out, _ = run(
        capsys,
        "learn",
        "mc-prediction",
        "slippery-gridworld",
        "--episodes",
        "200",
        "--seed",
        "0",
        "--json",
        "--plot",
        str(path),
    )
    assert code == 0 and json.loads(out)["episodes"] == 200
    assert path.read_bytes()[:8] == PNG
