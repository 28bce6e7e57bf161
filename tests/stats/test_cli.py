"""``policylab stats DIR [DIR ...]`` on hand-written sweep folders."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from policylab.cli.main import main
from policylab.stats import probability_of_improvement, summarize

from .test_sweeps import trial, write_sweep

# seeds 0..4 of two configurations on two tasks; "fast" beats "slow" on both
SCORES = {
    "fast": [[0.9, 0.7], [0.8, 0.75], [1.0, 0.6], [0.85, 0.8], [0.95, 0.65]],
    "slow": [[0.5, 0.2], [0.6, 0.3], [0.4, 0.25], [0.55, 0.1], [0.45, 0.35]],
}


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(argv)
        raise SystemExit(0)
    out = capsys.readouterr()
    return int(exc.value.code or 0), out.out, out.err


@pytest.fixture
def sweeps(tmp_path: Path) -> list[Path]:
    folders = []
    for task, name in enumerate(["FrozenLake-v1", "CliffWalking-v1"]):
        trials = [
            trial(label, seed, rows[seed][task])
            for label, rows in SCORES.items()
            for seed in range(5)
        ]
        trials.append(trial("broken", 0, 0.0, status="ERROR"))
        folders.append(write_sweep(tmp_path / f"task{task}", trials, problem=name))
    return folders


def test_json_gives_summaries_of_the_runs_x_tasks_matrices(
    sweeps: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["stats", *map(str, sweeps), "--json", "--reps", "500", "--seed", "3"]
    code, out, err = run([*argv, "--out", str(tmp_path / "figs")], capsys)
    assert code == 0, err
    doc = json.loads(out)
    assert doc["tasks"] == ["FrozenLake-v1", "CliffWalking-v1"]
    assert list(doc["configs"]) == ["fast", "slow"]  # best IQM first
    for label, rows in SCORES.items():
        entry = doc["configs"][label]
        assert entry["runs"] == 5 and entry["tasks"] == 2 and entry["seeds"] == [0, 1, 2, 3, 4]
        assert entry["scores"] == rows
        expected = summarize(np.array(rows), reps=500, seed=3)
        for name, values in expected.items():
            assert entry[name] == values
    poi = doc["probability_of_improvement"]
    assert poi["best"] == doc["best"] == "fast"
    assert poi["over"]["slow"]["value"] == probability_of_improvement(
        SCORES["fast"], SCORES["slow"]
    )
    assert poi["over"]["slow"]["value"] == 1.0
    assert any("1 of 11 runs" in n for n in doc["notes"])
    names = sorted(Path(p).name for p in doc["figures"])
    assert names == ["aggregates.png", "learning_curves.png", "performance_profiles.png"]
    for p in doc["figures"]:
        assert Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_table_for_people(sweeps: list[Path], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["stats", str(sweeps[0]), "--no-figures", "--reps", "300"], capsys)
    assert code == 0
    fast = summarize(np.array(SCORES["fast"])[:, :1], reps=300, seed=0)["iqm"]
    lines = out.splitlines()
    assert lines[0] == (
        "q-learning on FrozenLake-v1: score (mean return of the last 10% of episodes)"
    )
    row = next(line for line in lines if line.startswith("fast"))
    assert f"{fast['value']:.3f} [{fast['low']:.3f}, {fast['high']:.3f}]" in row
    assert row.rstrip().endswith("best")
    assert "value [low, high]: 95% stratified bootstrap percentile intervals (300" in out
    assert "wrote" not in out


def test_normalize_confidence_and_threshold(
    sweeps: list[Path], capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["stats", str(sweeps[1]), "--json", "--no-figures", "--reps", "200"]
    code, out, _ = run([*argv, "--normalize", "0,0.5", "--confidence", "0.8"], capsys)
    assert code == 0
    doc = json.loads(out)
    assert doc["normalize"] == [0.0, 0.5] and doc["confidence"] == 0.8
    x = np.array(SCORES["fast"])[:, 1:] / 0.5
    assert doc["configs"]["fast"]["iqm"] == summarize(x, reps=200, confidence=0.8)["iqm"]
    code, out, _ = run([*argv, "--threshold", "0.5"], capsys)
    gap = json.loads(out)["configs"]["slow"]["optimality_gap"]["value"]
    assert gap == pytest.approx(0.5 - np.minimum(np.array(SCORES["slow"])[:, 1], 0.5).mean())


@pytest.mark.parametrize(
    ("make", "extra", "words"),
    [
        (lambda d: d.mkdir(), [], "holds no sweep.json"),
        (lambda d: None, [], "does not exist"),
        (lambda d: (d.mkdir(), (d / "sweep.json").write_text("{oops")), [], "invalid JSON"),
        (
            lambda d: write_sweep(d, [], version=9),
            [],
            "has version 9; this policylab reads version 1",
        ),
        (lambda d: write_sweep(d, []), [], "no configuration has a finished 'score'"),
        (lambda d: write_sweep(d, [trial("a", 0, 1.0)]), ["--normalize", "1"], "MIN,MAX"),
        (lambda d: write_sweep(d, [trial("a", 0, 1.0)]), ["--reps", "0"], "--reps must be a"),
        (
            lambda d: write_sweep(d, [trial("a", 0, 1.0)]),
            ["--confidence", "1.5"],
            "confidence must be in (0, 1); got 1.5",
        ),
        (lambda d: write_sweep(d, [trial("a", 0, 1.0)]), ["--seed", "-2"], "--seed must be"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: object, extra: list[str], words: str
) -> None:
    folder = tmp_path / "sweep"
    make(folder)  # type: ignore[operator]
    code, out, err = run(["stats", str(folder), "--no-figures", *extra], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("policylab: error: "), err
    assert words in err


def test_figures_folder_is_checked_before_any_work(
    sweeps: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, _, err = run(["stats", str(sweeps[0]), "--out", str(blocker)], capsys)
    assert code == 2 and "--out" in err and "is an existing file" in err
