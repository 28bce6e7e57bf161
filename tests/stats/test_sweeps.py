"""Reading sweep folders: the sweep.json contract, score matrices matched by seed."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from policylab.exceptions import CheckpointError, InvalidArgumentError, RunFolderError
from policylab.stats.sweeps import read_sweep, score_matrices


def trial(label: str, seed: int, score: Any, status: str = "TERMINATED", **extra: Any) -> dict:
    return {
        "trial_id": f"{label}-{seed}",
        "config": {},
        "config_label": label,
        "seed": seed,
        "status": status,
        "metrics": {"score": score, "steps": 100},
        "curve": extra.pop("curve", {"x": [0, 1, 2], "y": [0.0, score / 2, score]}),
        **extra,
    }


def write_sweep(folder: Path, trials: list[dict], **fields: Any) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    doc = {
        "kind": "policylab-sweep",
        "version": 1,
        "command": "sweep",
        "algorithm": "q-learning",
        "problem": folder.name,
        "metric": "score",
        "mode": "max",
        "metric_description": "mean return of the last 10% of episodes",
        "trials": trials,
        "statistics": {},
        **fields,
    }
    (folder / "sweep.json").write_text(json.dumps(doc))
    (folder / "ray").mkdir(exist_ok=True)  # the sweep's own files are left alone
    return folder


def test_read_sweep_keeps_the_contract_fields(tmp_path: Path) -> None:
    d = write_sweep(tmp_path / "lake", [trial("a", 0, 0.5), trial("a", 1, float("nan"))])
    s = read_sweep(d)
    assert (s.algorithm, s.problem, s.metric, s.mode, s.command) == (
        "q-learning",
        "lake",
        "score",
        "max",
        "sweep",
    )
    assert [r.seed for r in s.runs] == [0, 1]
    assert s.runs[0].metrics == {"score": 0.5, "steps": 100.0}
    assert np.isnan(s.runs[1].metrics["score"])
    np.testing.assert_array_equal(s.runs[0].curve_x, [0, 1, 2])
    again = read_sweep(d / "sweep.json")  # the file itself names its folder
    assert again.folder == d and [r.metrics for r in again.runs] == [r.metrics for r in s.runs]


def test_matrices_match_runs_by_seed_across_tasks(tmp_path: Path) -> None:
    one = write_sweep(
        tmp_path / "one",
        [
            trial("a", 2, 0.2),
            trial("a", 0, 0.0),
            trial("a", 1, 0.1),
            trial("a", 7, 9.0),  # seed 7 did not run on task two: left out
            trial("b", 0, 0.5),
            trial("c", 0, 0.9),  # c is not on task two: left out
            trial("a", 3, 0.3, status="ERROR"),
        ],
    )
    two = write_sweep(
        tmp_path / "two",
        [
            trial("a", 1, 1.1),
            trial("a", 0, 1.0),
            trial("a", 2, 1.2),
            trial("a", 2, 5.0),  # a repeated (configuration, seed): counted once
            trial("b", 0, 1.5),
            trial("b", 1, float("inf")),  # not a finite score
        ],
    )
    mats, notes = score_matrices([read_sweep(one), read_sweep(two)])
    assert list(mats) == ["a", "b"]
    a = mats["a"]
    assert a.tasks == ("one", "two") and a.seeds == (0, 1, 2) and a.dropped == 1
    np.testing.assert_array_equal(a.scores, [[0.0, 1.0], [0.1, 1.1], [0.2, 1.2]])
    np.testing.assert_array_equal(mats["b"].scores, [[0.5, 1.5]])
    assert len(a.curves["one"]) == 3 and len(a.curves["two"]) == 3
    text = "\n".join(notes)
    assert "c: no finished run on two; left out" in text
    assert "a: 1 finished runs left out (their seed did not finish on every task)" in text
    assert "one: 1 of 7 runs have no finished 'score'" in text
    assert "two: 1 of 6 runs" in text and "two: 1 repeated" in text


def test_normalize_and_metric(tmp_path: Path) -> None:
    d = write_sweep(tmp_path / "cliff", [trial("a", 0, -100.0), trial("a", 1, -13.0)])
    mats, _ = score_matrices([read_sweep(d)], normalize=(-100, -13))
    np.testing.assert_allclose(mats["a"].scores, [[0.0], [1.0]])
    mats, _ = score_matrices([read_sweep(d)], normalize="-100,-13")
    np.testing.assert_allclose(mats["a"].scores, [[0.0], [1.0]])
    mats, _ = score_matrices([read_sweep(d)], metric="steps")
    np.testing.assert_array_equal(mats["a"].scores, [[100.0], [100.0]])
    with pytest.raises(InvalidArgumentError, match="normalize needs min < max; got min 1"):
        score_matrices([read_sweep(d)], normalize=(1, 1))
    with pytest.raises(InvalidArgumentError, match="two numbers MIN,MAX"):
        score_matrices([read_sweep(d)], normalize="0;1")
    with pytest.raises(InvalidArgumentError, match="no configuration has a finished 'nope'"):
        score_matrices([read_sweep(d)], metric="nope")


def test_sweeps_of_different_metrics_need_a_metric(tmp_path: Path) -> None:
    a = write_sweep(tmp_path / "a", [trial("x", 0, 1.0)])
    b = write_sweep(tmp_path / "b", [trial("x", 0, 1.0)], metric="steps")
    with pytest.raises(InvalidArgumentError, match=r"different metrics \(score, steps\)"):
        score_matrices([read_sweep(a), read_sweep(b)])
    mats, _ = score_matrices([read_sweep(a), read_sweep(b)], metric="score")
    assert mats["x"].scores.shape == (1, 2)


def _raw(folder: Path, text: str) -> Path:
    folder.mkdir()
    (folder / "sweep.json").write_text(text)
    return folder


@pytest.mark.parametrize(
    ("text", "error", "words"),
    [
        ("{not json", CheckpointError, "invalid JSON at line 1, column 2"),
        ("[1, 2]", RunFolderError, "is not a policylab sweep"),
        ('{"kind": "other", "version": 1}', RunFolderError, "kind 'other'"),
        ('{"kind": "policylab-sweep", "version": 2, "trials": []}', RunFolderError, "version 2"),
        ('{"kind": "policylab-sweep", "version": 1, "trials": 3}', CheckpointError, "'trials'"),
        (
            '{"kind": "policylab-sweep", "version": 1, "trials": [{"seed": 1}]}',
            CheckpointError,
            "trials[0] has no 'config_label'",
        ),
        (
            '{"kind": "policylab-sweep", "version": 1, "trials": '
            '[{"config_label": "a", "seed": "1"}]}',
            CheckpointError,
            "trials[0] (a) has seed '1'; expected an integer",
        ),
        (
            '{"kind": "policylab-sweep", "version": 1, "trials": [{"config_label": "a", '
            '"seed": 1, "curve": {"x": [1, 2], "y": [1]}}]}',
            CheckpointError,
            "the curve has 2 x values and 1 y values",
        ),
        (
            '{"kind": "policylab-sweep", "version": 1, "mode": "best", "trials": []}',
            CheckpointError,
            "'mode' is 'best'",
        ),
    ],
)
def test_malformed_sweep_files(tmp_path: Path, text: str, error: type, words: str) -> None:
    with pytest.raises(error) as info:
        read_sweep(_raw(tmp_path / "s", text))
    assert words in str(info.value)


def test_folders_that_hold_no_sweep(tmp_path: Path) -> None:
    with pytest.raises(RunFolderError, match="does not exist"):
        read_sweep(tmp_path / "nowhere")
    with pytest.raises(RunFolderError, match="holds no sweep.json"):
        read_sweep(tmp_path)
    (tmp_path / "f.txt").write_text("x")
    with pytest.raises(RunFolderError, match="is a file"):
        read_sweep(tmp_path / "f.txt")
