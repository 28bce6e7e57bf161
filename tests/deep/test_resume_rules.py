"""Resume rules of deep runs: annealing on resume, log columns, refusals, the JSON summary."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path
from typing import Any

import pytest
from cli_helpers import run_cli

import policylab.deep as deep
from policylab.deep.common.logging import RunLogger
from policylab.exceptions import InvalidArgumentError, RunFolderError, TrainingInterrupted

SMALL: dict[str, Any] = dict(n_envs=2, n_steps=32, n_epochs=1, batch_size=64, hidden=(8,))


class _Recorder:
    """Callback: (steps at the iteration's start, its learning rate); stops at ``stop_at``."""

    def __init__(self, start: int, stop_at: int | None = None) -> None:
        self.t, self.stop_at = start, stop_at
        self.seen: list[tuple[int, float]] = []

    def __call__(self, agent: deep.Agent, metrics: dict[str, float]) -> bool:
        self.seen.append((self.t, metrics["learning_rate"]))
        self.t = agent.num_timesteps
        return self.stop_at is None or agent.num_timesteps < self.stop_at


def test_ppo_annealing_continues_on_resume_and_never_jumps_on_extension(tmp_path: Path) -> None:
    lr0, total = 1e-3, 640
    run = tmp_path / "run"
    agent = deep.PPO("CartPole-v1", learning_rate=lr0, anneal_lr=True, **SMALL)
    first = _Recorder(0, stop_at=320)
    agent.learn(total, callback=first, run_dir=run)  # stopped early: saved at ~320 steps
    stopped = agent.num_timesteps
    assert 320 <= stopped < total
    for t, lr in first.seen:
        assert lr == pytest.approx(lr0 * (1 - t / total), rel=1e-12)

    resumed = deep.PPO.resume(run)
    assert resumed.num_timesteps == stopped and resumed.target_steps == total
    second = _Recorder(stopped)
    resumed.learn(total, callback=second, run_dir=run)  # the same target: the same schedule
    for t, lr in second.seen:
        assert lr == pytest.approx(lr0 * (1 - t / total), rel=1e-12)
    assert second.seen[0][1] == pytest.approx(lr0 * (1 - stopped / total))

    # extension after stopping early: from the rate reached, linearly to 0 at the new end
    ext = deep.PPO("CartPole-v1", learning_rate=lr0, anneal_lr=True, **SMALL)
    before = _Recorder(0, stop_at=320)
    ext.learn(total, callback=before, run_dir=tmp_path / "ext")
    t0 = ext.num_timesteps
    p0 = 1 - t0 / total
    again = deep.PPO.resume(tmp_path / "ext")
    after = _Recorder(t0)
    again.learn(2 * total, callback=after, run_dir=tmp_path / "ext")
    for t, lr in after.seen:
        assert lr == pytest.approx(lr0 * p0 * (2 * total - t) / (2 * total - t0), rel=1e-12)
    rates = [lr for _, lr in before.seen + after.seen]
    assert all(b <= a + 1e-15 for a, b in itertools.pairwise(rates))
    # the schedule's anchor is part of the checkpoint
    assert deep.PPO.resume(tmp_path / "ext").progress_remaining == pytest.approx(
        again.progress_remaining
    )


def test_progress_csv_has_every_column_and_is_cut_back_to_the_checkpoint(tmp_path: Path) -> None:
    log = RunLogger(tmp_path, tensorboard=False)
    log.log(10, {"a": 1.0, "recent_return": None})
    log.log(20, {"a": 2.0, "recent_return": 5.0, "loss": 0.5})  # a new column appears
    log.log(30, {"a": 3.0, "recent_return": 6.0, "loss": 0.25})
    log.close()
    with (tmp_path / "progress.csv").open(newline="") as f:
        rows = list(csv.reader(f))
    assert rows == [
        ["step", "a", "recent_return", "loss"],
        ["10", "1.0", "", ""],
        ["20", "2.0", "5.0", "0.5"],
        ["30", "3.0", "6.0", "0.25"],
    ]
    with (tmp_path / "progress.csv").open("a") as f:
        f.write("40,4.0,7")  # a row cut by a kill
    RunLogger(tmp_path, tensorboard=False, resume_step=20).close()
    with (tmp_path / "progress.csv").open(newline="") as f:
        assert [r[0] for r in csv.reader(f)] == ["step", "10", "20"]


def test_dqn_log_gets_loss_columns_after_learning_starts(tmp_path: Path) -> None:
    agent = deep.DQN(
        "CartPole-v1", learning_starts=300, log_interval=100, hidden=(8,), buffer_size=1000
    )
    agent.learn(600, run_dir=tmp_path / "run")
    with (tmp_path / "run" / "progress.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert "loss" in rows[0] and "recent_return" in rows[0]
    assert rows[0]["loss"] == "" and rows[-1]["loss"] != ""


def test_python_learn_refuses_a_foreign_run_and_too_few_steps(tmp_path: Path) -> None:
    run = tmp_path / "run"
    deep.PPO("CartPole-v1", **SMALL).learn(64, run_dir=run)
    with pytest.raises(RunFolderError, match="already holds a run"):
        deep.PPO("CartPole-v1", **SMALL).learn(64, run_dir=run)
    agent = deep.PPO.resume(run)
    with pytest.raises(InvalidArgumentError, match="below the"):
        agent.learn(10, run_dir=run)
    agent.learn(agent.num_timesteps + 64, run_dir=run)  # its own run: continues


def test_resume_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    base = ["train", "ppo", "CartPole-v1", "--out", str(run), "--no-progress"]
    tiny = ["--set", "n_envs=2", "--set", "n_steps=32", "--set", "hidden=[8]"]
    code, _, err = run_cli([*base, "--steps", "64", "--eval-episodes", "0", *tiny], capsys)
    assert code == 0, err
    cases = [
        (["train", "dqn", "CartPole-v1", "--out", str(run), "--resume"], "is a ppo run on"),
        (["train", "ppo", "Acrobot-v1", "--out", str(run), "--resume"], "not ppo on Acrobot-v1"),
        ([*base, "--resume", "--set", "gamma=0.5"], "--set gamma cannot change a resumed run"),
        ([*base, "--resume", "--steps", "10"], "is below the"),
        ([*base, "--resume", "--seed", "3"], "differs from the run's seed 0"),
        ([*base, "--resume", "--config", str(run / "run.json")], "--config cannot change"),
        ([*base, "--resume", "--steps", "1000"], "annealed its learning rate to 0"),
        ([*base, "--steps", "64"], "already holds a run; pass --resume"),
    ]
    for argv, words in cases:
        code, _, err = run_cli(argv, capsys)
        assert code == 2, (argv, err)
        assert words in err and err.count("\n") == 1, (argv, err)
    # without run.json (a folder from agent.save), the checkpoint names the run
    (run / "run.json").unlink()
    code, _, err = run_cli(["train", "dqn", "CartPole-v1", "--out", str(run), "--resume"], capsys)
    assert code == 2 and "is a ppo run on CartPole-v1, not dqn" in err
    code, _, err = run_cli(["train", "ppo", "Acrobot-v1", "--out", str(run), "--resume"], capsys)
    assert code == 2 and "not ppo on Acrobot-v1" in err


def test_train_json_summary_and_generic_defaults_note(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--steps", "64", "--out", str(tmp_path / "r"), "--json",
         "--eval-episodes", "2", "--set", "n_envs=2", "--set", "n_steps=32"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    doc = json.loads(out)  # stdout is exactly one JSON object
    assert doc["algo"] == "ppo" and doc["env_id"] == "CartPole-v1" and doc["steps"] >= 64
    assert doc["resumed_from"] is None and len(doc["eval"]["returns"]) == 2
    assert doc["eval"]["mean"] == pytest.approx(sum(doc["eval"]["returns"]) / 2)
    assert "checkpoint every 10,000 steps" in err

    code, out, err = run_cli(["train", "ppo", "MountainCarContinuous-v0", "--dry-run"], capsys)
    assert code == 0, err
    assert "no tuned hyperparameters for ppo on MountainCarContinuous-v0; using generic" in err
    code, out, err = run_cli(["train", "ppo", "CartPole-v1", "--dry-run"], capsys)
    assert code == 0 and "no tuned" not in err


@pytest.mark.parametrize(("signum", "code"), [(2, 130), (15, 143)])
def test_interrupted_training_exits_128_plus_the_signal(
    signum: int,
    code: int,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def stopped(self: deep.Agent, *args: Any, **kwargs: Any) -> None:
        raise TrainingInterrupted(1234, "run", signum)

    monkeypatch.setattr(deep.Agent, "learn", stopped)
    got, _, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--out", str(tmp_path / "r"), "--no-progress"], capsys
    )
    assert got == code
    assert err.strip().splitlines()[-1] == "interrupted at step 1,234; continue with --resume"
