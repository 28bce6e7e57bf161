"""Gymnasium vector environments for the deep agents (``gymnasium.vector``).

An env id becomes ``gymnasium.make_vec``: the NumPy-vectorised implementation where
the environment has one (CartPole), otherwise a ``SyncVectorEnv``. Atari ids
(``ALE/Pong-v5``) get Gymnasium's ``AtariPreprocessing`` (no-op starts, frame skip 4,
84x84 grey frames) and ``FrameStackObservation`` (4 frames). All vector envs run in
Gymnasium's default next-step autoreset mode, which the agents rely on.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from policylab.exceptions import InvalidArgumentError

__all__ = [
    "check_env_id",
    "env_id_of",
    "is_atari_id",
    "make_env",
    "make_vec_env",
    "space_from_json",
    "space_to_json",
]

EnvLike = str | gym.Env[Any, Any] | VectorEnv


def is_atari_id(env_id: str) -> bool:
    """Whether ``env_id`` names an Arcade Learning Environment game."""
    return env_id.startswith("ALE/") or "NoFrameskip" in env_id


def _register_ale() -> None:
    try:
        import ale_py
    except ImportError:  # pragma: no cover - depends on the install
        raise InvalidArgumentError(
            "Atari environments need ale-py: pip install 'policylab[deep]'"
        ) from None
    gym.register_envs(ale_py)


def make_env(env_id: str, render_mode: str | None = None, **kwargs: Any) -> gym.Env[Any, Any]:
    """One environment by id (with the Atari preprocessing for ALE games).

    Raises:
        InvalidArgumentError: If Gymnasium does not know the id.
    """
    if is_atari_id(env_id):
        _register_ale()
        env = _make(env_id, render_mode=render_mode, frameskip=1, **kwargs)
        env = gym.wrappers.AtariPreprocessing(env, noop_max=30, frame_skip=4, screen_size=84)
        return gym.wrappers.FrameStackObservation(env, 4)
    return _make(env_id, render_mode=render_mode, **kwargs)


def _missing_dependency(env_id: str, e: BaseException) -> InvalidArgumentError:
    """The error for an env whose package is not installed, naming what to install."""
    text = str(e).lower()
    if "box2d" in text:
        how = "Box2D, which is not installed: pip install 'policylab[box2d]'"
    elif "mujoco" in text:
        how = "MuJoCo, which is not installed: pip install 'gymnasium[mujoco]'"
    else:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        how = f"a package that is not installed ({first})"
    return InvalidArgumentError(f"Gymnasium environment {env_id!r} needs {how}")


def _make(env_id: str, **kwargs: Any) -> gym.Env[Any, Any]:
    try:
        return gym.make(env_id, **kwargs)
    except (gym.error.DependencyNotInstalled, ImportError) as e:
        raise _missing_dependency(env_id, e) from None
    except gym.error.Error as e:
        raise InvalidArgumentError(f"cannot make Gymnasium environment {env_id!r}: {e}") from None


def check_env_id(env_id: str) -> Any:
    """The Gymnasium spec of ``env_id`` (registering the Atari games for ``ALE/`` ids).

    Raises:
        InvalidArgumentError: If Gymnasium does not know the id.
    """
    if is_atari_id(env_id):
        _register_ale()
    try:
        return gym.spec(env_id)
    except gym.error.Error as e:
        raise InvalidArgumentError(f"unknown Gymnasium environment {env_id!r}: {e}") from None


def make_vec_env(env: EnvLike, n_envs: int = 1) -> VectorEnv:
    """A Gymnasium vector env of ``n_envs`` copies of ``env`` (an id, an env, or a vector env).

    Raises:
        InvalidArgumentError: If ``env`` cannot be vectorised as asked, or a vector env
            given does not use next-step autoreset.
    """
    if int(n_envs) != n_envs or n_envs < 1:
        raise InvalidArgumentError(f"n_envs must be an integer >= 1; got {n_envs!r}")
    if isinstance(env, VectorEnv):
        venv = env
    elif isinstance(env, str):
        if is_atari_id(env):
            _register_ale()
            venv = gym.vector.SyncVectorEnv([lambda: make_env(env) for _ in range(n_envs)])
        else:
            spec = check_env_id(env)
            mode = "vector_entry_point" if spec.vector_entry_point is not None else "sync"
            try:
                venv = gym.make_vec(env, num_envs=n_envs, vectorization_mode=mode)
            except (gym.error.DependencyNotInstalled, ImportError) as e:
                raise _missing_dependency(env, e) from None
    elif isinstance(env, gym.Env):
        if n_envs == 1:
            venv = gym.vector.SyncVectorEnv([lambda: env])
        elif env.spec is not None:
            spec = env.spec
            venv = gym.vector.SyncVectorEnv([lambda: gym.make(spec) for _ in range(n_envs)])
        else:
            raise InvalidArgumentError(
                f"n_envs={n_envs} copies need an env id or an env made with gymnasium.make "
                "(it has a "
                "spec); pass the id, a vector env, or n_envs=1"
            )
    else:
        raise InvalidArgumentError(
            "env must be a Gymnasium id, a gymnasium.Env or a gymnasium.vector.VectorEnv; "
            f"got {type(env).__name__}"
        )
    mode_of = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
    if mode_of != AutoresetMode.NEXT_STEP:
        raise InvalidArgumentError(
            f"vector envs must use autoreset_mode=NEXT_STEP (Gymnasium's default); got {mode_of}"
        )
    return venv


def env_id_of(env: EnvLike) -> str | None:
    """The Gymnasium id behind ``env`` if it has one (to re-make it later), else None."""
    if isinstance(env, str):
        return env
    spec = getattr(env, "spec", None)
    if spec is None and isinstance(env, gym.vector.SyncVectorEnv) and env.envs:
        spec = env.envs[0].spec
    if spec is None:
        return None
    return str(spec.id)


def space_to_json(space: gym.Space[Any]) -> dict[str, Any]:
    """A Box or Discrete space as plain JSON (to rebuild an agent's networks on load)."""
    if isinstance(space, gym.spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, gym.spaces.Box):

        def bound(a: np.ndarray) -> Any:
            flat = a.reshape(-1)
            if flat.size and np.all(flat == flat[0]):
                return float(flat[0])
            return [float(x) for x in flat]

        return {
            "type": "Box", "shape": list(space.shape), "dtype": str(space.dtype),
            "low": bound(space.low), "high": bound(space.high),
        }  # fmt: skip
    raise InvalidArgumentError(f"only Box and Discrete spaces are supported; got {space}")


def space_from_json(d: dict[str, Any]) -> gym.Space[Any]:
    """Inverse of :func:`space_to_json`."""
    if d.get("type") == "Discrete":
        return gym.spaces.Discrete(int(d["n"]), start=int(d.get("start", 0)))
    if d.get("type") == "Box":
        shape = tuple(int(x) for x in d["shape"])
        dtype = np.dtype(d["dtype"])

        def arr(v: Any) -> np.ndarray:
            return (
                np.full(shape, v, dtype=dtype)
                if np.isscalar(v)
                else np.asarray(v, dtype=dtype).reshape(shape)
            )

        return gym.spaces.Box(arr(d["low"]), arr(d["high"]), shape=shape, dtype=dtype)
    raise InvalidArgumentError(f"unknown space description {d!r}")
