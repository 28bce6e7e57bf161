"""Off-screen OpenGL for rendering MuJoCo environments on a machine without a display.

MuJoCo renders through one of three OpenGL back-ends, chosen by the ``MUJOCO_GL``
environment variable before MuJoCo first renders: ``glfw`` (a window, the default),
``egl`` (headless, on a GPU driver or Mesa) or ``osmesa`` (headless, Mesa's software
renderer). :func:`use_offscreen_gl` picks a headless one that works here.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

from policylab.exceptions import InvalidArgumentError

__all__ = ["BACKENDS", "is_mujoco_env", "use_offscreen_gl"]

BACKENDS = ("egl", "osmesa")
"""The headless back-ends tried, in order."""

_PROBE = "import mujoco; c = mujoco.GLContext(16, 16); c.make_current(); c.free()"


def is_mujoco_env(env_id: str | None) -> bool:
    """Whether Gymnasium's ``env_id`` is one of its MuJoCo environments."""
    if env_id is None:
        return False
    import gymnasium as gym

    try:
        entry = gym.spec(env_id).entry_point
    except gym.error.Error:
        return False
    return isinstance(entry, str) and entry.startswith("gymnasium.envs.mujoco")


def _works(backend: str) -> bool:
    env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    try:  # in a scratch folder: a failing MuJoCo writes MUJOCO_LOG.TXT where it runs
        with tempfile.TemporaryDirectory() as scratch:
            done = subprocess.run(
                [sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=60,
                cwd=scratch,
            )  # fmt: skip
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def use_offscreen_gl(env_id: str | None) -> str | None:
    """Set ``MUJOCO_GL`` to a headless back-end that works, for a MuJoCo ``env_id``.

    A ``MUJOCO_GL`` the user set is kept. Otherwise EGL, then OSMesa, is tried in a
    child process (a failed OpenGL start can abort a process), and the first that works
    is set for this one.

    Returns:
        The back-end in use, or None for an env that is not MuJoCo's.

    Raises:
        InvalidArgumentError: If neither back-end works, saying what to install.
    """
    if not is_mujoco_env(env_id):
        return None
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    for backend in BACKENDS:
        if _works(backend):
            os.environ["MUJOCO_GL"] = backend
            os.environ.setdefault("PYOPENGL_PLATFORM", backend)
            return backend
    raise InvalidArgumentError(
        f"cannot render {env_id!r} off-screen: neither MuJoCo's EGL nor its OSMesa back-end "
        "starts here. Install one (Debian/Ubuntu: apt install libegl1 libegl-mesa0, or "
        "apt install libosmesa6), or set MUJOCO_GL=glfw on a machine with a display"
    )
