"""``record``: the file format follows the suffix; a headless machine gets no SDL noise."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

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


def test_record_on_a_headless_machine_keeps_sdl_off_the_display(
    agent: deep.PPO, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # without a display SDL probes for one and prints "XDG_RUNTIME_DIR is invalid or not
    # set"; rgb_array frames need none, so record selects SDL's dummy video driver
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER"):
        monkeypatch.delenv(var, raising=False)
    record_gif(agent, tmp_path / "e.gif", max_steps=2)
    assert os.environ["SDL_VIDEODRIVER"] == "dummy"
    monkeypatch.delenv("SDL_VIDEODRIVER")
    monkeypatch.setenv("DISPLAY", ":0")  # a desktop keeps its own driver
    record_gif(agent, tmp_path / "f.gif", max_steps=2)
    assert "SDL_VIDEODRIVER" not in os.environ


def test_every_kth_frame_is_kept(agent: deep.PPO, tmp_path: Path) -> None:
    # frames at steps 0, k, 2k, ... of the episode (the others are not rendered at all)
    ret, n = record_gif(agent, tmp_path / "all.gif", max_steps=9)
    ret3, n3 = record_gif(agent, tmp_path / "third.gif", max_steps=9, every=3)
    assert ret3 == ret == n - 1  # the same episode (a deterministic policy, the same seed)
    assert n3 == 1 + int(ret) // 3


def test_a_walker_is_rendered_through_its_tracking_camera() -> None:
    mujoco = pytest.importorskip("mujoco")
    from policylab.deep.common.envs import make_env
    from policylab.deep.record import _follow_walker

    env = make_env("Walker2d-v5", render_mode="rgb_array")
    renderer = env.unwrapped.mujoco_renderer  # type: ignore[attr-defined]
    assert renderer.camera_id == -1  # Gymnasium's default: a free camera that stays put
    _follow_walker(env)
    track = mujoco.mj_name2id(renderer.model, mujoco.mjtObj.mjOBJ_CAMERA, "track")
    assert track != -1 and renderer.camera_id == track
    assert renderer.model.cam_mode[track] == mujoco.mjtCamLight.mjCAMLIGHT_TRACKCOM
    env.close()
    other = make_env("Walker2d-v5", render_mode="rgb_array", camera_id=0)
    _follow_walker(other)  # a camera chosen at make is kept
    assert other.unwrapped.mujoco_renderer.camera_id == 0  # type: ignore[attr-defined]
    other.close()
