"""The deep commands with SAC/TD3 and the walking reward: train, eval --json, resume, record."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_helpers import run_cli as _run

SMALL = ["--set", "hidden=[16]", "--set", "learning_starts=50", "--set", "batch_size=16",
         "--set", "buffer_size=1000", "--no-progress"]  # fmt: skip


def test_train_walking_reward_eval_both_resume_record(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    code, out, err = _run(
        ["train", "sac", "Hopper-v5", "--reward", "walking", "--v-max", "1.5", "--steps", "120",
         "--out", str(run), "--eval-episodes", "2", *SMALL],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert "walking reward" in out
    doc = json.loads((run / "run.json").read_text())
    assert doc["reward"] == {"name": "walking", "v_max": 1.5} and doc["algo"] == "sac"

    code, out, err = _run(["eval", str(run), "--episodes", "2", "--json"], capsys)
    assert code == 0, err
    ev = json.loads(out)
    assert set(ev) == {"mean", "std", "returns", "walking"}
    assert len(ev["walking"]["returns"]) == 2 and ev["walking"]["returns"] != ev["returns"]

    code, out, err = _run(
        ["train", "sac", "Hopper-v5", "--out", str(run), "--resume", "--steps", "180",
         "--eval-episodes", "0", "--no-progress"],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert "resuming" in out and "180" in out
    assert json.loads((run / "run.json").read_text())["reward"]["name"] == "walking"

    code, out, err = _run(["record", str(run), "--max-steps", "3"], capsys)
    assert code == 0, err
    assert (run / "episode.gif").read_bytes()[:6] in (b"GIF87a", b"GIF89a")


def test_train_td3_pendulum_env_reward(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    code, out, err = _run(
        ["train", "td3", "Pendulum-v1", "--steps", "100", "--out", str(run),
         "--eval-episodes", "1", *SMALL],
        capsys,
    )  # fmt: skip
    assert code == 0, err
    assert "walking" not in out
    assert json.loads((run / "run.json").read_text())["reward"] == {"name": "env"}


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "sac", "CartPole-v1", "--steps", "10"], "continuous action space"),
        (["train", "td3", "Pendulum-v1", "--reward", "walking", "--steps", "10"], "Pendulum-v1"),
        (["train", "sac", "Hopper-v5", "--reward", "walking", "--v-max", "0"], "v_max"),
        (["train", "sac", "Hopper-v5", "--v-max", "2", "--steps", "10"], "--reward walking"),
        (["train", "sac", "Hopper-v5", "--reward", "fast", "--steps", "10"], "reward must be"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, _, err = _run([*argv, "--out", str(tmp_path / "r"), "--no-progress"], capsys)
    assert code == 2, err
    assert message in err and "Traceback" not in err


def test_dry_run_lists_zoo_defaults_for_walkers(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(["train", "td3", "Walker2d-v5", "--dry-run"], capsys)
    assert code == 0 and "policy_delay" in out and "1,000,000 steps" in out


def test_record_without_offscreen_gl_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from policylab.deep import mujoco_gl
    from policylab.exceptions import InvalidArgumentError

    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.setattr(mujoco_gl, "_works", lambda backend: False)
    with pytest.raises(InvalidArgumentError, match="libosmesa6"):
        mujoco_gl.use_offscreen_gl("Walker2d-v5")
    assert mujoco_gl.use_offscreen_gl("CartPole-v1") is None
    monkeypatch.setattr(mujoco_gl, "_works", lambda backend: backend == "osmesa")
    assert mujoco_gl.use_offscreen_gl("Walker2d-v5") == "osmesa"
