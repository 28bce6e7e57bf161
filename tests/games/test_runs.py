"""Run folders of the game learners: a lock, no silent reuse, Ctrl-C keeps the checkpoint."""

from __future__ import annotations

import json

import pytest

from policylab.cli.main import main
from policylab.exceptions import CheckpointError, InvalidArgumentError
from policylab.games.runs import open_run, trim_log


def test_lock_refuses_a_second_holder(tmp_path):
    with (
        open_run(tmp_path / "r", resume=False),
        pytest.raises(InvalidArgumentError, match="in use by another process"),
        open_run(tmp_path / "r", resume=False),
    ):
        pass
    with open_run(tmp_path / "r", resume=False):  # released after the block
        pass
    with (
        pytest.raises(CheckpointError, match="nothing to resume"),
        open_run(tmp_path / "empty", resume=True),
    ):
        pass


def test_trim_log_drops_rows_past_the_checkpoint(tmp_path):
    (tmp_path / "progress.csv").write_text("step,a\n1,0.5\n2,0.25\n3,0.1\n")
    trim_log(tmp_path, 2)
    assert (tmp_path / "progress.csv").read_text() == "step,a\n1,0.5\n2,0.25\n"


def test_ctrl_c_keeps_the_last_checkpoint_and_exits_130(tmp_path, monkeypatch, capsys):
    import policylab.games.learned as learned

    real = learned.train_chunk

    def interrupted(V, cfg, chunk):
        if chunk == 2:
            raise KeyboardInterrupt
        return real(V, cfg, chunk)

    monkeypatch.setattr(learned, "train_chunk", interrupted)
    out = tmp_path / "td"
    args = ["train", "selfplay-td", "tic-tac-toe", "--out", str(out), "--no-progress"]
    with pytest.raises(SystemExit) as exc:
        main([*args, "--set", "episodes=3000", "--set", "chunks=3"])
    assert exc.value.code == 130
    assert json.loads((out / "run.json").read_text())["chunks_done"] == 2
    assert "--resume" in capsys.readouterr().out
    monkeypatch.setattr(learned, "train_chunk", real)
    with pytest.raises(SystemExit) as exc:
        main([*args, "--resume"])
        raise SystemExit(0)
    assert (exc.value.code or 0) == 0
    assert json.loads((out / "run.json").read_text())["episodes_done"] == 3000
