"""``record``: the file format follows the suffix; a headless machine gets no SDL noise."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")
import policylab.deep as deep
from policylab.deep.record import record_gif
from policylab.exceptions import InvalidArgumentError


@pytest.fixture(scope="module")
def agent() -> deep.PPO:
    return deep.PPO("CartPole-v1", n_envs=1, n_steps=16, hidden=(8,))


@pytest.mark.parametrize(
    ("suffix", "magic"), [(".gif", b"GIF89a"), (".png", b"\x89PNG\r\n\x1a\n"), (".webp", b"RIFF")]
)
def test_format_follows_the_suffix(
    agent: deep.PPO, tmp_path: Path, suffix: str, magic: bytes
) -> None:
    path = tmp_path / f"episode{suffix}"
    ret, n = record_gif(agent, path, max_steps=4)
    data = path.read_bytes()
    assert data.startswith(magic) and n >= 2 and ret == n - 1  # CartPole pays 1 per step
    if suffix == ".png":
        assert b"acTL" in data  # an animated PNG, not a GIF under a .png name


def test_other_suffixes_are_refused_before_playing(agent: deep.PPO, tmp_path: Path) -> None:
    with pytest.raises(InvalidArgumentError, match=r"suffix '\.bmp'"):
        record_gif(agent, tmp_path / "x.bmp")
    assert list(tmp_path.iterdir()) == []


def test_record_on_a_headless_machine_prints_no_sdl_error(agent: deep.PPO, tmp_path: Path) -> None:
    agent.save(tmp_path / "agent.pt")
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("XDG_RUNTIME_DIR", "SDL_VIDEODRIVER", "WAYLAND_DISPLAY")
    }
    env.pop("DISPLAY", None)
    done = subprocess.run(
        [sys.executable, "-m", "policylab", "record", str(tmp_path / "agent.pt"),
         "--out", str(tmp_path / "e.gif"), "--max-steps", "3"],
        capture_output=True, text=True, timeout=120, env=env,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "XDG_RUNTIME_DIR" not in done.stderr + done.stdout
    assert (tmp_path / "e.gif").read_bytes()[:6] == b"GIF89a"
