"""A GIF of one episode of an agent, from the environment's rgb_array frames."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from policylab.deep.common.agent import Agent
from policylab.deep.common.checkpoint import atomic_write_bytes
from policylab.deep.common.envs import make_env
from policylab.exceptions import InvalidArgumentError

__all__ = ["record_gif"]


def record_gif(
    agent: Agent,
    path: str | Path,
    seed: int = 0,
    max_steps: int = 1000,
    fps: int = 30,
    every: int = 1,
) -> tuple[float, int]:
    """Play one greedy episode of ``agent`` on its env and write its frames as a GIF.

    Returns:
        ``(episode return, number of frames written)``.
    """
    from PIL import Image

    if agent.env_id is None:
        raise InvalidArgumentError("the agent has no env id to render")
    if fps < 1 or every < 1 or max_steps < 1:
        raise InvalidArgumentError(
            f"fps, every and max_steps must be >= 1; got {fps}, {every}, {max_steps}"
        )
    env = make_env(agent.env_id, render_mode="rgb_array")
    try:
        obs, _ = env.reset(seed=seed)
        frames = [env.render()]
        total = 0.0
        for _ in range(max_steps):
            obs, r, term, trunc, _ = env.step(agent.predict(obs, deterministic=True))
            total += float(r)
            frames.append(env.render())
            if term or trunc:
                break
    finally:
        env.close()
    images = [
        Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames[::every] if f is not None
    ]
    if not images:
        raise InvalidArgumentError(f"{agent.env_id!r} rendered no rgb_array frames")
    import io

    buf = io.BytesIO()
    images[0].save(
        buf,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(1, 1000 // fps),
        loop=0,
    )
    atomic_write_bytes(path, buf.getvalue())
    return total, len(images)
