"""An animation of one episode of an agent, from the environment's rgb_array frames."""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from policylab.deep.common.agent import Agent
from policylab.deep.common.envs import make_env
from policylab.exceptions import InvalidArgumentError
from policylab.runs import atomic_write_bytes
from policylab.validation import check_count, check_output_file, check_seed

__all__ = ["ANIMATION_FORMATS", "record_gif"]

ANIMATION_FORMATS = {".gif": "GIF", ".png": "PNG", ".webp": "WEBP"}
"""File suffix -> image format of the animation (``.png`` is an animated PNG)."""


def _follow_walker(env: Any) -> None:
    """Render a MuJoCo walker through its model's own tracking camera, if it has one.

    Gymnasium's MuJoCo walkers render ``rgb_array`` frames through a free camera that
    stays where the episode started, so a walker that walks leaves the picture within
    seconds. Their models define a camera named ``track`` that follows the walker's
    centre of mass (``mode="trackcom"``); this renders through it instead. An env
    without one, or rendered through a camera chosen at ``make``, is left alone.
    """
    renderer = getattr(env.unwrapped, "mujoco_renderer", None)
    if renderer is None or getattr(renderer, "camera_id", None) != -1:
        return
    import mujoco

    track = mujoco.mj_name2id(renderer.model, mujoco.mjtObj.mjOBJ_CAMERA, "track")
    if track != -1:
        renderer.camera_id = track


def record_gif(
    agent: Agent,
    path: str | Path,
    seed: int = 0,
    max_steps: int = 1000,
    fps: int = 30,
    every: int = 1,
) -> tuple[float, int]:
    """Play one greedy episode of ``agent`` on its env and write its frames as an animation.

    The format follows the suffix of ``path``: ``.gif`` (GIF), ``.png`` (animated PNG)
    or ``.webp`` (animated WebP); the path is checked before the episode is played.

    Args:
        agent: A trained agent with an env id.
        path: The file to write.
        seed: Seed of the episode's reset.
        max_steps: Stop the episode after this many steps.
        fps: Frames per second of the animation.
        every: Keep every k-th frame (smaller files).

    Returns:
        ``(episode return, number of frames written)``.

    Raises:
        InvalidArgumentError: On a path that cannot be written or has another suffix, on
            counts below 1, or if the env renders no frames.
    """
    target = check_output_file(path, "the animation file", suffixes=ANIMATION_FORMATS)
    seed_ = check_seed(seed)
    max_steps = check_count(max_steps, "max_steps")
    fps = check_count(fps, "fps")
    every = check_count(every, "every")
    if agent.env_id is None:
        raise InvalidArgumentError("the agent has no env id to render")
    from PIL import Image

    # rgb_array frames need no window; on a machine without a display SDL (pygame) would
    # probe for one and print "XDG_RUNTIME_DIR is invalid or not set" on stderr
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    env = make_env(agent.env_id, render_mode="rgb_array")
    _follow_walker(env)
    try:
        obs, _ = env.reset(seed=seed_)
        frames = [env.render()]
        total = 0.0
        for t in range(1, max_steps + 1):
            obs, r, term, trunc, _ = env.step(agent.predict(obs, deterministic=True))
            total += float(r)
            if t % every == 0:  # only the frames kept are rendered (rendering is the cost)
                frames.append(env.render())
            if term or trunc:
                break
    finally:
        env.close()
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames if f is not None]
    if not images:
        raise InvalidArgumentError(f"{agent.env_id!r} rendered no rgb_array frames")
    buf = io.BytesIO()
    images[0].save(
        buf,
        format=ANIMATION_FORMATS[target.suffix.lower()],
        save_all=True,
        append_images=images[1:],
        duration=max(1, 1000 // fps),
        loop=0,
    )
    atomic_write_bytes(target, buf.getvalue())
    return total, len(images)
