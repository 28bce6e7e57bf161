"""Gymnasium vector environments for the deep agents (``gymnasium.vector``).

An env id becomes ``gymnasium.make_vec``: the NumPy-vectorised implementation where
the environment has one (CartPole; policylab's :class:`AcrobotVectorEnv` for
Acrobot-v1), otherwise a ``SyncVectorEnv``. One copy of an env that has a vectorised
implementation is stepped as the single env instead (:class:`OneEnvVector`): NumPy's
per-call cost on arrays of one element makes the vectorised step several times slower
than the scalar one there. Atari ids
(``ALE/Pong-v5``) get Gymnasium's ``AtariPreprocessing`` (no-op starts, frame skip 4,
84x84 grey frames) and ``FrameStackObservation`` (4 frames). All vector envs run in
Gymnasium's default next-step autoreset mode, which the agents rely on.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.classic_control.acrobot import AcrobotEnv
from gymnasium.vector import AutoresetMode, VectorEnv
from numpy.typing import NDArray

from policylab.exceptions import InvalidArgumentError

__all__ = [
    "AcrobotVectorEnv",
    "OneEnvVector",
    "ScalarAcrobotEnv",
    "acrobot_derivatives",
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
            vectorised = env == "Acrobot-v1" or spec.vector_entry_point is not None
            if n_envs == 1 and env == "Acrobot-v1":  # Gymnasium's env, stepped on floats
                return OneEnvVector(
                    gym.make(dataclasses.replace(spec, entry_point=ScalarAcrobotEnv))
                )
            if n_envs == 1 and vectorised:
                return OneEnvVector(_make(env))
            if env == "Acrobot-v1":
                return AcrobotVectorEnv(n_envs)
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


def acrobot_derivatives(
    theta1: Any, theta2: Any, dtheta1: Any, dtheta2: Any, a: Any, cos: Any, sin: Any
) -> tuple[Any, Any, Any, Any]:
    """d/dt (theta1, theta2, dtheta1, dtheta2) of the Acrobot under torque ``a``.

    Sutton and Barto's "book" equations with Gymnasium's constants (masses, lengths and
    moments of inertia 1, centres of mass at 0.5, g = 9.8), the operations of
    ``gymnasium.envs.classic_control.AcrobotEnv._dsdt`` in its order:

        d1 = m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos theta2) + I1 + I2
        d2 = m2 (lc2^2 + l1 lc2 cos theta2) + I2
        phi2 = m2 lc2 g cos(theta1 + theta2 - pi/2)
        phi1 = -m2 l1 lc2 dtheta2^2 sin theta2 - 2 m2 l1 lc2 dtheta2 dtheta1 sin theta2
               + (m1 lc1 + m2 l1) g cos(theta1 - pi/2) + phi2
        ddtheta2 = (a + d2/d1 phi1 - m2 l1 lc2 dtheta1^2 sin theta2 - phi2)
                   / (m2 lc2^2 + I2 - d2^2/d1)
        ddtheta1 = -(d2 ddtheta2 + phi1) / d1

    Elementwise: on floats with ``math.cos``/``math.sin``, or on arrays with NumPy's.
    """
    m1 = m2 = 1.0
    l1, lc1, lc2 = 1.0, 0.5, 0.5
    I1 = I2 = 1.0  # the moments of inertia, named as in AcrobotEnv
    g = 9.8
    pi = np.pi
    cos2, sin2 = cos(theta2), sin(theta2)  # each computed once, used as before
    d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * cos2) + I1 + I2
    d2 = m2 * (lc2**2 + l1 * lc2 * cos2) + I2
    phi2 = m2 * lc2 * g * cos(theta1 + theta2 - pi / 2.0)
    phi1 = (
        -m2 * l1 * lc2 * dtheta2**2 * sin2
        - 2 * m2 * l1 * lc2 * dtheta2 * dtheta1 * sin2
        + (m1 * lc1 + m2 * l1) * g * cos(theta1 - pi / 2)
        + phi2
    )
    ddtheta2 = (a + d2 / d1 * phi1 - m2 * l1 * lc2 * dtheta1**2 * sin2 - phi2) / (
        m2 * lc2**2 + I2 - d2**2 / d1
    )
    ddtheta1 = -(d2 * ddtheta2 + phi1) / d1
    return dtheta1, dtheta2, ddtheta1, ddtheta2


def _axpy(y: list[float], h: float, k: tuple[float, ...]) -> list[float]:
    """Y + h k, elementwise (a Runge-Kutta stage's state)."""
    return [yi + h * ki for yi, ki in zip(y, k, strict=True)]


class ScalarAcrobotEnv(AcrobotEnv):
    """Gymnasium's ``AcrobotEnv`` with its step computed on Python floats.

    The same operations in the same order as ``AcrobotEnv.step`` (fourth-order
    Runge-Kutta over dt = 0.2 through :func:`acrobot_derivatives`, angles wrapped to
    [-pi, pi], velocities clipped), on floats instead of NumPy scalars and arrays of
    five, with ``math.cos`` and ``math.sin`` where Gymnasium calls NumPy's on float64
    scalars (both the C library's functions here: the tests compare whole episodes
    with Gymnasium's env bit for bit): about 7 us a step instead of 28. Reset, seeding,
    spaces and rendering are Gymnasium's. Torque noise or the "nips" dynamics fall
    back to Gymnasium's step.
    """

    def step(self, a: Any) -> tuple[NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        """One step of ``dt`` under the torque of action ``a`` (0, 1, 2: -1, 0, +1)."""
        s = self.state
        if s is None or self.torque_noise_max > 0 or self.book_or_nips != "book":
            return super().step(a)  # type: ignore[no-any-return,no-untyped-call]
        cos, sin, pi = math.cos, math.sin, np.pi
        y0 = [float(v) for v in s]
        torque = float(self.AVAIL_TORQUE[a])
        dt = self.dt - 0  # rk4 over t = [0, dt], as gymnasium's acrobot.rk4
        dt2 = dt / 2.0
        k1 = acrobot_derivatives(*y0, torque, cos, sin)
        k2 = acrobot_derivatives(*_axpy(y0, dt2, k1), torque, cos, sin)
        k3 = acrobot_derivatives(*_axpy(y0, dt2, k2), torque, cos, sin)
        k4 = acrobot_derivatives(*_axpy(y0, dt, k3), torque, cos, sin)
        ns = [
            y + dt / 6.0 * (p + 2 * q + 2 * r + w)
            for y, p, q, r, w in zip(y0, k1, k2, k3, k4, strict=True)
        ]
        for i in (0, 1):  # wrap(x, -pi, pi)
            while ns[i] > pi:
                ns[i] = ns[i] - 2 * pi
            while ns[i] < -pi:
                ns[i] = ns[i] + 2 * pi
        ns[2] = min(max(ns[2], -self.MAX_VEL_1), self.MAX_VEL_1)
        ns[3] = min(max(ns[3], -self.MAX_VEL_2), self.MAX_VEL_2)
        self.state = np.array(ns)
        terminated = bool(-cos(ns[0]) - cos(ns[1] + ns[0]) > 1.0)
        if self.render_mode == "human":
            self.render()
        obs = np.array([cos(ns[0]), sin(ns[0]), cos(ns[1]), sin(ns[1]), ns[2], ns[3]])
        return obs.astype(np.float32), -1.0 if not terminated else 0.0, terminated, False, {}


class AcrobotVectorEnv(VectorEnv):
    """Gymnasium's Acrobot-v1, N copies stepped together with NumPy.

    The same dynamics as ``gymnasium.envs.classic_control.AcrobotEnv`` (Sutton and
    Barto's equations, "book" variant, fourth-order Runge-Kutta over dt = 0.2, angles
    wrapped to [-pi, pi], velocities clipped at 4 pi and 9 pi, reward -1 per step and 0
    on reaching the height), the same operations in the same order on arrays instead of
    scalars, with its 500-step time limit and Gymnasium's next-step autoreset, as
    Gymnasium's own ``CartPoleVectorEnv`` does for CartPole. Like that one it draws
    the start states of all copies from one generator (so a seed gives other episodes
    than a ``SyncVectorEnv`` of single envs, equally distributed). A ``SyncVectorEnv``
    of single Acrobots costs a Python call and a dozen tiny NumPy calls per copy and
    Runge-Kutta stage; this costs them once for all copies.

    Args:
        num_envs: Number of copies N.
        max_episode_steps: The time limit (500 for Acrobot-v1).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    dt = 0.2
    LINK_LENGTH_1 = 1.0
    LINK_MASS_1 = 1.0
    LINK_MASS_2 = 1.0
    LINK_COM_POS_1 = 0.5
    LINK_COM_POS_2 = 0.5
    LINK_MOI = 1.0
    MAX_VEL_1 = 4 * np.pi
    MAX_VEL_2 = 9 * np.pi
    AVAIL_TORQUE = np.array([-1.0, 0.0, +1])

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 500) -> None:
        from gymnasium.vector.utils import batch_space

        self.num_envs = int(num_envs)
        self.max_episode_steps = int(max_episode_steps)
        high = np.array([1.0, 1.0, 1.0, 1.0, self.MAX_VEL_1, self.MAX_VEL_2], dtype=np.float32)
        self.single_observation_space = gym.spaces.Box(low=-high, high=high, dtype=np.float32)
        self.single_action_space = gym.spaces.Discrete(3)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.state = np.zeros((4, self.num_envs))
        self.steps = np.zeros(self.num_envs, dtype=np.int32)
        self.prev_done = np.zeros(self.num_envs, dtype=np.bool_)

    def _start_states(self, n: int) -> NDArray[np.float32]:
        """(4, n) start states: AcrobotEnv.reset's uniform(-0.1, 0.1, 4) in float32, per copy."""
        out = self.np_random.uniform(low=-0.1, high=0.1, size=(n, 4)).astype(np.float32)
        return np.ascontiguousarray(out.T)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float32], dict[str, Any]]:
        """Start every copy afresh (``seed`` seeds the generator of the start states)."""
        super().reset(seed=seed)
        start = self._start_states(self.num_envs)
        self.state = start.astype(np.float64)
        self.steps = np.zeros(self.num_envs, dtype=np.int32)
        self.prev_done = np.zeros(self.num_envs, dtype=np.bool_)
        return self._observe(start), {}

    def _dsdt(self, s_augmented: NDArray[np.float64]) -> NDArray[np.float64]:
        """AcrobotEnv._dsdt on (5, N) states (theta1, theta2, dtheta1, dtheta2, torque)."""
        a = s_augmented[-1]
        theta1, theta2, dtheta1, dtheta2 = s_augmented[:-1]
        derivs = acrobot_derivatives(theta1, theta2, dtheta1, dtheta2, a, np.cos, np.sin)
        return np.stack((*derivs, np.zeros_like(a)))

    def step(
        self, actions: NDArray[Any]
    ) -> tuple[
        NDArray[np.float32],
        NDArray[np.float64],
        NDArray[np.bool_],
        NDArray[np.bool_],
        dict[str, Any],
    ]:
        """Step every copy; a copy whose episode ended on the previous step resets instead."""
        a = np.asarray(actions)
        if a.shape != (self.num_envs,) or a.dtype.kind not in "iu" or a.min() < 0 or a.max() > 2:
            raise InvalidArgumentError(
                f"actions must be {self.num_envs} integers in 0..2; got {actions!r}"
            )
        y0 = np.concatenate([self.state, self.AVAIL_TORQUE[a][None]])
        # rk4 over t = [0, dt], as gymnasium's acrobot.rk4
        dt = np.float64(self.dt) - np.float64(0.0)
        dt2 = dt / 2.0
        k1 = self._dsdt(y0)
        k2 = self._dsdt(y0 + dt2 * k1)
        k3 = self._dsdt(y0 + dt2 * k2)
        k4 = self._dsdt(y0 + dt * k3)
        ns = (y0 + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))[:4]
        for i in (0, 1):  # wrap(x, -pi, pi): whole turns off, one at a time
            while np.any(big := ns[i] > np.pi):
                ns[i] = np.where(big, ns[i] - 2 * np.pi, ns[i])
            while np.any(small := ns[i] < -np.pi):
                ns[i] = np.where(small, ns[i] + 2 * np.pi, ns[i])
        ns[2] = np.minimum(np.maximum(ns[2], -self.MAX_VEL_1), self.MAX_VEL_1)
        ns[3] = np.minimum(np.maximum(ns[3], -self.MAX_VEL_2), self.MAX_VEL_2)
        self.state = ns
        terminated = -np.cos(ns[0]) - np.cos(ns[1] + ns[0]) > 1.0
        reward = np.where(terminated, 0.0, -1.0)
        self.steps += 1
        truncated = self.steps >= self.max_episode_steps
        # next-step autoreset: the copies that ended on the previous step start again
        reset = self.prev_done
        obs = self._observe(ns)
        if reset.any():
            start = self._start_states(int(reset.sum()))
            self.state[:, reset] = start
            obs[reset] = self._observe(start)  # from the float32 state, as AcrobotEnv
            self.steps[reset] = 0
            reward[reset] = 0.0
            terminated[reset] = False
            truncated[reset] = False
        self.prev_done = terminated | truncated
        return obs, reward, terminated, truncated, {}

    @staticmethod
    def _observe(s: NDArray[Any]) -> NDArray[np.float32]:
        """AcrobotEnv._get_ob of (4, n) states: (n, 6) cos, sin of both angles, velocities."""
        cos, sin = np.cos, np.sin
        return np.stack([cos(s[0]), sin(s[0]), cos(s[1]), sin(s[1]), s[2], s[3]], axis=1).astype(
            np.float32
        )


class OneEnvVector(VectorEnv):
    """One environment as a vector env of one copy, in next-step autoreset mode.

    What ``SyncVectorEnv([lambda: env])`` gives (observations, rewards, terminated and
    truncated flags with a leading axis of 1; ``reset(seed=s)`` seeds the env with s;
    the step after an episode's end resets the env and reports reward 0, not
    terminated, not truncated), for a few microseconds a step: no per-step info
    merging, no batched copies through the space utilities. The infos are not
    forwarded (the agents do not read them).

    Args:
        env: The environment (a ``gymnasium.make`` env with a Box or Discrete
            observation space).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012

    def __init__(self, env: gym.Env[Any, Any]) -> None:
        from gymnasium.vector.utils import batch_space

        self.env = env
        self.num_envs = 1
        self.spec = env.spec
        self.single_observation_space = env.observation_space
        self.single_action_space = env.action_space
        self.observation_space = batch_space(env.observation_space, 1)
        self.action_space = batch_space(env.action_space, 1)
        self._obs_dtype = env.observation_space.dtype
        self._done = False

    def _batch(self, obs: Any) -> NDArray[Any]:
        return np.array(obs, dtype=self._obs_dtype)[None]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset the env (``seed`` seeds it, as ``SyncVectorEnv`` seeds its first env)."""
        super().reset(seed=seed)
        obs, _ = self.env.reset(seed=seed, options=options)
        self._done = False
        return self._batch(obs), {}

    def step(
        self, actions: NDArray[Any]
    ) -> tuple[
        NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]
    ]:
        """Step the env with ``actions[0]``, or reset it if its episode ended last step."""
        if self._done:
            obs, _ = self.env.reset()
            self._done = False
            no = np.zeros(1, dtype=np.bool_)
            return self._batch(obs), np.zeros(1), no, no.copy(), {}
        obs, reward, terminated, truncated, _ = self.env.step(actions[0])
        self._done = bool(terminated or truncated)
        return (
            self._batch(obs),
            np.array([reward], dtype=np.float64),
            np.array([terminated], dtype=np.bool_),
            np.array([truncated], dtype=np.bool_),
            {},
        )

    def close_extras(self, **kwargs: Any) -> None:
        """Close the env."""
        self.env.close()
