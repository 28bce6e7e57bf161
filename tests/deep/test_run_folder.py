"""Run folders with real processes: Ctrl-C, kill -9, two commands at once, resume rules.

Each test starts a real ``policylab train`` process on a tiny PPO (a few thousand steps
per second), signals or kills it, and checks what is left in the folder.
"""

from __future__ import annotations

import csv
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import run_cli

from policylab.deep.common.checkpoint import load_checkpoint

TINY = [
    "--set", "n_envs=4", "--set", "n_steps=32", "--set", "n_epochs=1", "--set", "hidden=[8]",
    "--set", "batch_size=128", "--set", "anneal_lr=false", "--set", "log_interval=256",
]  # fmt: skip


def _start(run: Path, *extra: str) -> subprocess.Popen[str]:
    argv = [sys.executable, "-m", "policylab", "train", "ppo", "CartPole-v1",
            "--steps", "50000000", "--out", str(run), "--no-progress", "--eval-episodes", "0",
            *TINY, *extra]  # fmt: skip
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for(cond: object, proc: subprocess.Popen[str], timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    while not cond():  # type: ignore[operator]
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"training ended early ({proc.returncode}): {out}\n{err}")
        if time.monotonic() - t0 > timeout:
            proc.kill()
            pytest.fail("training did not reach the expected point in time")
        time.sleep(0.1)


def _steps(run: Path) -> tuple[list[str], list[int]]:
    with (run / "progress.csv").open(newline="") as f:
        rows = list(csv.reader(f))
    # a row being appended by the live process may be cut short: skip what does not parse
    return rows[0], [int(r[0]) for r in rows[1:] if len(r) == len(rows[0]) and r[0].isdigit()]


def _checkpoint_step(run: Path) -> int:
    return int(load_checkpoint(run / "checkpoint.pt")[0]["num_timesteps"])


def test_ctrl_c_saves_exits_130_and_a_second_command_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    proc = _start(run)
    try:
        _wait_for(
            lambda: len(_steps(run)[1]) >= 2 if (run / "progress.csv").exists() else False, proc
        )
        # a second command on the same folder, while the first one trains
        code, _, err = run_cli(
            ["train", "ppo", "CartPole-v1", "--out", str(run), "--resume", "--no-progress"], capsys
        )
        assert code == 2 and err.count("\n") == 1
        assert f"in use by process {proc.pid}" in err and "choose another folder" in err
        code, _, err = run_cli(["train", "ppo", "CartPole-v1", "--out", str(run)], capsys)
        assert code == 2 and "in use by process" in err
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    m = re.search(r"interrupted at step ([\d,]+); continue with --resume", err)
    assert m, err
    step = int(m.group(1).replace(",", ""))
    assert _checkpoint_step(run) == step
    header, steps = _steps(run)
    assert steps and max(steps) <= step
    assert "checkpoint every 10,000 steps" in out

    # the same folder continues; the log stays one table with increasing steps
    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--out", str(run), "--resume", "--steps",
         str(step + 512), "--no-progress", "--eval-episodes", "0"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert f"resuming {run} at step {step:,} of {step + 512:,}" in out
    assert _checkpoint_step(run) >= step + 512
    header2, steps2 = _steps(run)
    assert header2[: len(header)] == header
    assert steps2 == sorted(set(steps2)) and steps2[: len(steps)] == steps


def test_kill_9_leaves_a_periodic_checkpoint_and_the_log_is_cut_back_on_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    proc = _start(run, "--set", "checkpoint_every=2048")
    try:
        # killed after the first periodic checkpoint, with rows logged after it: the
        # process is frozen (SIGSTOP) while the folder is checked, so nothing races
        def past_checkpoint() -> bool:
            if not (run / "checkpoint.pt").exists():
                return False
            proc.send_signal(signal.SIGSTOP)
            if max(_steps(run)[1]) > _checkpoint_step(run):
                return True
            proc.send_signal(signal.SIGCONT)
            return False

        _wait_for(past_checkpoint, proc)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    ckpt = _checkpoint_step(run)
    assert max(_steps(run)[1]) > ckpt  # the log ran ahead of the checkpoint
    (run / ".checkpoint.pt.k1ll3d.tmp").write_bytes(b"half a checkpoint")  # a killed write

    code, out, err = run_cli(["eval", str(run), "--episodes", "1", "--json"], capsys)
    assert code == 0, err
    assert len(json.loads(out)["returns"]) == 1

    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--out", str(run), "--resume", "--steps",
         str(ckpt + 256), "--no-progress", "--eval-episodes", "0", "--json"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert f"took over the lock left by process {proc.pid}" in err
    assert re.search(r"removed [12] temporary file", err)  # 2 if it was killed mid-save
    assert not list(run.glob(".*.tmp"))
    doc = json.loads(out)
    assert doc["resumed_from"] == ckpt and doc["steps"] >= ckpt + 256
    _, steps = _steps(run)
    assert steps == sorted(set(steps))  # rows after the old checkpoint were cut, not kept
    first_after = next(s for s in steps if s > ckpt)
    assert first_after > ckpt and all(s <= ckpt or s >= first_after for s in steps)
