"""Run folders of the game learners: the shared run-folder rules, Ctrl-C, kill, workers.

The in-process tests check the rules and messages; the real-process ones start
``policylab train`` and signal or kill it, as a user or a batch scheduler would.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from policylab.exceptions import CheckpointError, RunFolderError, TrainingInterrupted
from policylab.games import TIC_TAC_TOE
from policylab.games.learned import load_player, train_selfplay_td
from policylab.games.runs import game_run
from policylab.games.selfplay_td import SelfPlayTDConfig, TDPlayer

pytest.importorskip("torch")

# the helpers of the deep run-folder tests: run the CLI in-process, wait on a live run
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "deep"))
from cli_helpers import run_cli as _cli
from test_run_folder import _wait_for

TD_ARGS = ["train", "selfplay-td", "tic-tac-toe", "--no-progress"]


def test_a_second_holder_and_the_new_or_resume_rule(tmp_path: Path) -> None:
    with (
        game_run(tmp_path / "r", resume=False, algo="selfplay-td", game="tic-tac-toe"),
        pytest.raises(RunFolderError, match=f"in use by process {os.getpid()}"),
        game_run(tmp_path / "r", resume=False, algo="selfplay-td", game="tic-tac-toe"),
    ):
        pass
    with game_run(tmp_path / "r", resume=False, algo="selfplay-td", game="tic-tac-toe"):
        pass  # released after the block, and the empty folder holds no run
    with (
        pytest.raises(RunFolderError, match="holds no run to resume"),
        game_run(tmp_path / "empty", resume=True, algo="alphazero", game="tic-tac-toe"),
    ):
        pass
    (tmp_path / "r" / "run.json").write_text('{"algo": "selfplay-td", "game": "tic-tac-toe"}')
    with (
        pytest.raises(RunFolderError, match="stopped before its first checkpoint"),
        game_run(tmp_path / "r", resume=True, algo="selfplay-td", game="tic-tac-toe"),
    ):
        pass


def test_resume_refuses_another_learner_and_leftover_temps_go(tmp_path: Path) -> None:
    run = tmp_path / "td"
    train_selfplay_td(run, SelfPlayTDConfig(episodes=200, chunks=2))
    with pytest.raises(
        RunFolderError, match="is a selfplay-td run on tic-tac-toe, not alphazero on tic-tac-toe"
    ):
        from policylab.games.alphazero import train_alphazero

        train_alphazero("tic-tac-toe", run, resume=True)
    (run / ".checkpoint.pt.123.tmp").write_bytes(b"half")  # a writer killed mid-write
    train_selfplay_td(run, resume=True)
    assert not (run / ".checkpoint.pt.123.tmp").exists()
    with pytest.raises(CheckpointError, match="not a game learner's run folder"):
        load_player(tmp_path, TIC_TAC_TOE)


def test_ctrl_c_saves_the_chunk_and_exits_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import policylab.games.learned as learned

    real = learned.train_chunk

    def ctrl_c_in_chunk_1(V, cfg, chunk):  # type: ignore[no-untyped-def]
        if chunk == 1:
            os.kill(os.getpid(), signal.SIGINT)  # delivered to the run's handler
        return real(V, cfg, chunk)

    monkeypatch.setattr(learned, "train_chunk", ctrl_c_in_chunk_1)
    out = tmp_path / "td"
    args = [*TD_ARGS, "--out", str(out)]
    code, _, err = _cli([*args, "--set", "episodes=4000", "--set", "chunks=4"], capsys)
    assert code == 130
    assert "interrupted at game 2,000; continue with --resume" in err
    assert json.loads((out / "run.json").read_text())["episodes_done"] == 2000
    with pytest.raises(TrainingInterrupted) as exc:  # the library raises, after saving
        train_selfplay_td(tmp_path / "lib", SelfPlayTDConfig(episodes=4000, chunks=4))
    assert exc.value.step == 2000 and exc.value.signal == signal.SIGINT
    monkeypatch.setattr(learned, "train_chunk", real)
    code, _, err = _cli([*args, "--resume"], capsys)
    assert code == 0, err
    assert json.loads((out / "run.json").read_text())["episodes_done"] == 4000
    # the interrupted and resumed table is the one of an uninterrupted run
    one_go = train_selfplay_td(tmp_path / "one", SelfPlayTDConfig(episodes=4000, chunks=4))
    resumed = load_player(out, TIC_TAC_TOE)
    assert isinstance(resumed, TDPlayer) and np.array_equal(resumed.values, one_go.values)


def test_alphazero_resume_cuts_the_log_back_to_the_checkpoint(tmp_path: Path) -> None:
    from policylab.games.alphazero import default_config, train_alphazero

    tiny = dict(
        iterations=2, games_per_iteration=2, simulations=4, eval_simulations=4, train_steps=2,
        batch_size=16, eval_games=0, workers=0, channels=4, blocks=0,
    )  # fmt: skip
    run = tmp_path / "az"
    train_alphazero("tic-tac-toe", run, default_config("tic-tac-toe", **tiny))
    log = run / "progress.csv"
    header = log.read_text().splitlines()[0]
    with log.open("a") as f:  # a row logged after the checkpoint, then a line cut by a kill
        f.write("3" + ",0.5" * (header.count(",")) + "\n4,0.")
    train_alphazero("tic-tac-toe", run, resume=True, iterations=3)
    steps = [ln.split(",")[0] for ln in log.read_text().splitlines()[1:]]
    assert steps == ["1", "2", "3"]
    assert "0.5,0.5,0.5" not in log.read_text()  # the stale row 3 is gone, the new one kept


# ------------------------------------------------------------------ real processes


def _episodes_done(run: Path) -> int:
    try:
        return int(json.loads((run / "run.json").read_text())["episodes_done"])
    except (OSError, ValueError, KeyError):
        return -1


def test_real_process_lock_and_ctrl_c(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "td"
    argv = [sys.executable, "-m", "policylab", *TD_ARGS, "--out", str(run),
            "--set", "episodes=200000000", "--set", "chunks=20000"]  # fmt: skip
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: _episodes_done(run) > 0, proc)
        code, _, err = _cli([*TD_ARGS, "--out", str(run), "--resume"], capsys)
        assert code == 2 and err.count("\n") == 1
        assert f"in use by process {proc.pid}" in err and "choose another folder" in err
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    done = _episodes_done(run)
    assert f"interrupted at game {done:,}; continue with --resume" in err
    assert "Traceback" not in err
    from policylab.deep.common.checkpoint import load_checkpoint

    assert load_checkpoint(run / "checkpoint.pt")[0]["episodes_done"] == done


def _workers(pid: int) -> list[int]:
    """The multiprocessing workers that process ``pid`` started (not its resource tracker)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
                cmdline = (d / "cmdline").read_bytes()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid and b"spawn_main" in cmdline:
                out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _start_alphazero(run: Path) -> subprocess.Popen[str]:
    sets = dict(
        iterations=1000, games_per_iteration=4000, simulations=50, workers=1, channels=4, blocks=0
    )
    argv = [sys.executable, "-m", "policylab", "train", "alphazero", "tic-tac-toe", "--out",
            str(run), "--no-progress"]  # fmt: skip
    for k, v in sets.items():
        argv += ["--set", f"{k}={v}"]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _playing(pid: int) -> bool:
    """Whether a worker has loaded torch (it is playing its share of the self-play games)."""
    try:
        return b"libtorch" in Path(f"/proc/{pid}/maps").read_bytes()
    except OSError:
        return False


def _wait_for_workers(proc: subprocess.Popen[str]) -> list[int]:
    # the worker busy with games that would take it minutes to finish
    _wait_for(lambda: any(_playing(w) for w in _workers(proc.pid)), proc)
    return _workers(proc.pid)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("how", [signal.SIGTERM, signal.SIGKILL])
def test_alphazero_leaves_no_workers_behind(tmp_path: Path, how: signal.Signals) -> None:
    run = tmp_path / "az"
    proc = _start_alphazero(run)
    workers: list[int] = []
    try:
        workers = _wait_for_workers(proc)
        proc.send_signal(how)
        _, err = proc.communicate(timeout=60)
        if how == signal.SIGTERM:
            assert proc.returncode == 143, err
            assert re.search(r"interrupted at iteration \d+; continue with --resume", err), err
        t0 = time.monotonic()
        while any(_alive(w) for w in workers) and time.monotonic() - t0 < 10:
            time.sleep(0.1)
        assert not [w for w in workers if _alive(w)], "self-play workers outlived the run"
    finally:
        if proc.poll() is None:
            proc.kill()
        for w in workers:  # whatever the test found, leave no process behind
            if _alive(w):
                os.kill(w, signal.SIGKILL)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_alphazero_stops_when_a_worker_dies(tmp_path: Path) -> None:
    run = tmp_path / "az"
    proc = _start_alphazero(run)
    workers: list[int] = []
    try:
        workers = _wait_for_workers(proc)
        os.kill(workers[0], signal.SIGKILL)  # as the out-of-memory killer would
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 1, err
        assert "a self-play worker process died" in err and "--resume" in err
        assert json.loads((run / "run.json").read_text())["iteration"] == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        for w in workers:
            if _alive(w):
                os.kill(w, signal.SIGKILL)
