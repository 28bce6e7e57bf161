"""RunFolder: the lock, the new-or-resume rule, stale files, atomic JSON, Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from policylab.exceptions import RunFolderError
from policylab.runs import LOCK_FILE, RunFolder, atomic_write_bytes


def test_second_opener_is_refused_and_the_lock_is_released_on_close(tmp_path: Path) -> None:
    run = tmp_path / "run"
    with RunFolder(run, command="policylab train ppo CartPole-v1") as first:
        record = json.loads((run / LOCK_FILE).read_text())
        assert record["pid"] == os.getpid() and record["command"].startswith("policylab train")
        with pytest.raises(RunFolderError, match=rf"in use by process {os.getpid()} "):
            RunFolder(run).open()
        assert first.is_open
    assert (run / LOCK_FILE).read_text() == ""  # closed cleanly: no owner record left
    with RunFolder(run) as again:
        assert again.stale_owner is None


def test_lock_held_by_another_live_process_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "run"
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from policylab.runs import RunFolder\n"
         f"r = RunFolder({str(run)!r}, command='holder'); r.open(); print('ok', flush=True)\n"
         "time.sleep(60)"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "ok"
        with pytest.raises(RunFolderError, match=rf"in use by process {holder.pid} \(holder"):
            RunFolder(run).open()
    finally:
        holder.kill()
        holder.wait()
    with RunFolder(run) as taken:  # killed: the kernel dropped its lock; the record is stale
        assert taken.stale_owner is not None and taken.stale_owner["pid"] == holder.pid


def test_stale_lock_record_of_a_dead_process_is_taken_over(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / LOCK_FILE).write_text(json.dumps({"pid": 4_000_000, "command": "gone"}) + "\n")
    with RunFolder(run) as r:
        assert r.stale_owner == {"pid": 4_000_000, "command": "gone"}
        assert json.loads((run / LOCK_FILE).read_text())["pid"] == os.getpid()


def test_new_run_refuses_an_existing_one_and_resume_needs_one(tmp_path: Path) -> None:
    run = tmp_path / "run"
    with pytest.raises(RunFolderError, match="holds no run to resume"):
        RunFolder(run, resume=True).open()
    assert not RunFolder(run, resume=True).is_open
    with RunFolder(run) as r:
        r.write_json("run.json", {"algo": "ppo", "steps": 3})
    with pytest.raises(RunFolderError, match="already holds a run; pass --resume"):
        RunFolder(run).open()
    with RunFolder(run, resume=True) as r:
        assert r.info == {"algo": "ppo", "steps": 3}
    # a folder with other files but no run is fine for a new run
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with RunFolder(other, markers=("run.json", "checkpoint.pt")):
        pass
    (tmp_path / "file").write_text("x")
    with pytest.raises(RunFolderError, match="is an existing file"):
        RunFolder(tmp_path / "file").open()


def test_stale_temporary_files_are_removed_on_open(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    stale = [run / ".checkpoint.pt.abc123.tmp", run / ".run.json.x.tmp"]
    for p in stale:
        p.write_bytes(b"half")
    (run / "keep.tmp").write_bytes(b"not ours")  # not a hidden atomic-write temp file
    with RunFolder(run) as r:
        assert sorted(r.removed_temps) == sorted(stale)
    assert not any(p.exists() for p in stale) and (run / "keep.tmp").exists()


def test_atomic_write_replaces_whole_file_and_leaves_no_temp(tmp_path: Path) -> None:
    p = tmp_path / "a" / "f.bin"
    atomic_write_bytes(p, b"a" * 100)
    atomic_write_bytes(p, b"b")
    assert p.read_bytes() == b"b"
    assert sorted(x.name for x in p.parent.iterdir()) == ["f.bin"]


def test_first_ctrl_c_sets_the_flag_second_raises(tmp_path: Path) -> None:
    before = signal.getsignal(signal.SIGINT)
    with RunFolder(tmp_path / "run") as r, r.catch_interrupts():
        assert not r.interrupted
        os.kill(os.getpid(), signal.SIGINT)
        assert r.interrupted and r.signal == signal.SIGINT
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


def test_sigterm_is_caught_like_ctrl_c_in_a_real_process(tmp_path: Path) -> None:
    script = (
        "import sys, time\n"
        "from policylab.runs import RunFolder\n"
        f"with RunFolder({str(tmp_path / 'run')!r}) as r, r.catch_interrupts():\n"
        "    print('ready', flush=True)\n"
        "    while not r.interrupted:\n"
        "        time.sleep(0.01)\n"
        "    print('saved after signal', r.signal, flush=True)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert out.strip() == f"saved after signal {int(signal.SIGTERM)}"
    assert "stopping after this iteration to save a checkpoint" in err
