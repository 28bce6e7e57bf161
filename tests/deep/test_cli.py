"""The deep RL commands: train, eval --json, record, resume, bad input; lazy torch import."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cli_helpers import run_cli


def test_train_eval_record_resume(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("n_envs = 2\nn_steps = 64\nn_epochs = 1\nhidden = [16, 16]\nanneal_lr = false\n")
    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--steps", "256", "--seed", "1", "--config", str(cfg),
         "--out", str(run),
         "--no-progress", "--eval-episodes", "2"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert "evaluation, 2 episodes" in out
    assert json.loads((run / "run.json").read_text())["config"]["hidden"] == [16, 16]

    code, out, err = run_cli(["eval", str(run), "--episodes", "3", "--json"], capsys)
    assert code == 0, err
    doc = json.loads(out)
    assert set(doc) == {"mean", "std", "returns"} and len(doc["returns"]) == 3
    assert doc["mean"] == pytest.approx(sum(doc["returns"]) / 3)

    code, out, err = run_cli(["record", str(run), "--max-steps", "20", "--every", "2"], capsys)
    assert code == 0, err
    gif = run / "episode.gif"
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")

    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--out", str(run), "--no-progress"], capsys
    )
    assert code == 2 and "--resume" in err

    code, out, err = run_cli(
        ["train", "ppo", "CartPole-v1", "--out", str(run), "--resume", "--steps", "512",
         "--no-progress",
         "--eval-episodes", "0"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert "resuming" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "a2c", "CartPole-v1"], "unknown algorithm"),
        (["train", "ppo", "NoSuchEnv-v0", "--steps", "10"], "NoSuchEnv-v0"),
        (["train", "ppo", "CartPole-v1", "--set", "n_steps=0", "--dry-run"], "n_steps"),
        (["eval", "/nonexistent/run"], "no checkpoint"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run_cli(argv, capsys)
    assert code == 2
    assert message in err and "Traceback" not in err


def test_dry_run_lists_tuned_config(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["train", "dqn", "CartPole-v1", "--dry-run"], capsys)
    assert code == 0 and "target_update_interval" in out


def test_import_policylab_does_not_import_torch() -> None:
    code = (
        "import sys, policylab; assert 'torch' not in sys.modules; "
        "policylab.deep.PPO; assert 'torch' in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
