"""The walking reward of Heess et al. (2017) for Gymnasium's MuJoCo walkers.

The "Deep Reinforcement Learning" lecture notes illustrate the reward hypothesis with a
robot that learns to walk from the reward of Heess et al. (2017), "Emergence of
Locomotion Behaviours in Rich Environments":

    r = min(v_x, v_max) - 0.005 (v_y^2 + v_z^2) - 0.05 y^2 - 0.02 ||u||^2 + 0.02

forward velocity rewarded up to a cap, sideways and vertical motion, drifting from the
track's centre line and effort penalised, and a small bonus for staying alive.
:class:`WalkingReward` computes it from the MuJoCo state of the walker's root body.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium.vector import VectorEnv
from numpy.typing import NDArray

from policylab.exceptions import InvalidArgumentError

__all__ = [
    "DEFAULT_V_MAX",
    "REWARDS",
    "WALKERS",
    "WalkingReward",
    "evaluate_walking",
    "resume_env",
    "reward_description",
    "reward_env",
    "run_reward",
    "walking_reward",
    "walking_vec_env",
]

DEFAULT_V_MAX = 3.0
"""The default speed cap v_max in m/s (policylab's choice; the paper leaves it to the task)."""

WALKERS: dict[str, str] = {
    "HalfCheetah": "planar",
    "Hopper": "planar",
    "Walker2d": "planar",
    "Ant": "free",
    "Humanoid": "free",
}
"""The supported Gymnasium MuJoCo walkers (any version, e.g. ``Walker2d-v5``) and how
their root body moves.

* ``planar`` (HalfCheetah, Hopper, Walker2d): the torso moves in the x-z plane through
  the joints ``rootx`` (slide along x: qpos[0], qvel[0] = v_x), ``rootz`` (slide along
  z: qpos[1], qvel[1] = v_z) and ``rooty`` (the pitch hinge). These walkers cannot leave
  the plane, so y = 0 and v_y = 0.
* ``free`` (Ant, Humanoid): the torso hangs on the free joint ``root``: qpos[0:3] is its
  position (x, y, z) and qvel[0:3] its linear velocity (v_x, v_y, v_z), both in the
  world frame; the walker starts at y = 0, on the track's centre line.
"""


def walking_reward(
    v_x: float, v_y: float, v_z: float, y: float, u: NDArray[Any], v_max: float
) -> float:
    """The walking reward of one step (Heess et al. 2017).

    r = min(v_x, v_max) - 0.005 (v_y^2 + v_z^2) - 0.05 y^2 - 0.02 ||u||^2 + 0.02

    Args:
        v_x: Forward velocity of the root body (m/s).
        v_y: Sideways velocity.
        v_z: Vertical velocity.
        y: Sideways distance from the track's centre line (m).
        u: The action (joint torques / actuator controls).
        v_max: The cap on the rewarded forward velocity.
    """
    effort = float(np.sum(np.square(np.asarray(u, dtype=np.float64))))
    return (
        min(float(v_x), float(v_max))
        - 0.005 * (float(v_y) ** 2 + float(v_z) ** 2)
        - 0.05 * float(y) ** 2
        - 0.02 * effort
        + 0.02
    )


def _family(env: gym.Env[Any, Any]) -> str:
    spec = env.spec
    env_id = spec.id if spec is not None else type(env.unwrapped).__name__
    name = env_id.split("/")[-1].split("-v")[0]
    kind = WALKERS.get(name)
    unwrapped = env.unwrapped
    if kind is None or not hasattr(unwrapped, "data") or not hasattr(unwrapped, "model"):
        raise InvalidArgumentError(
            f"the walking reward does not know how to read the root body of {env_id!r}; "
            f"supported MuJoCo walkers: {', '.join(f'{w}-v5' for w in WALKERS)}"
        )
    import mujoco

    model = unwrapped.model
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    expected_ok = (
        names[:2] == ["rootx", "rootz"]
        if kind == "planar"
        else int(model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)
    )
    if not expected_ok:
        raise InvalidArgumentError(
            f"{env_id!r} does not have the {kind} root joints the walking reward reads "
            f"(its first joints are {names[:3]})"
        )
    return kind


class WalkingReward(gym.Wrapper[Any, Any, Any, Any], gym.utils.RecordConstructorArgs):
    """Replace a MuJoCo walker's reward by the walking reward of Heess et al. (2017).

    r = min(v_x, v_max) - 0.005 (v_y^2 + v_z^2) - 0.05 y^2 - 0.02 ||u||^2 + 0.02,

    read after each step from the root body's joints (see :data:`WALKERS` for which
    joints each walker has), with u the action clipped to the action space. The env's
    own reward is kept in ``info["env_reward"]``; its terminations (a fallen Hopper or
    Walker2d) and time limit are unchanged.

    Args:
        env: HalfCheetah, Hopper, Walker2d, Ant or Humanoid (any version).
        v_max: The cap on the rewarded forward velocity, in m/s (> 0).

    Raises:
        InvalidArgumentError: For an env whose root body it cannot read, or v_max <= 0.

    Example:
        >>> import gymnasium as gym
        >>> import policylab as pl
        >>> env = pl.deep.WalkingReward(gym.make("Walker2d-v5"), v_max=3.0)  # doctest: +SKIP
    """

    def __init__(self, env: gym.Env[Any, Any], v_max: float = DEFAULT_V_MAX) -> None:
        if not isinstance(v_max, int | float) or not math.isfinite(v_max) or v_max <= 0:
            raise InvalidArgumentError(f"v_max must be a finite number > 0 (m/s); got {v_max!r}")
        gym.utils.RecordConstructorArgs.__init__(self, v_max=v_max)
        gym.Wrapper.__init__(self, env)
        self.kind = _family(env)
        self.v_max = float(v_max)
        space = env.action_space
        assert isinstance(space, gym.spaces.Box)
        self._low, self._high = space.low, space.high

    def root_state(self) -> tuple[float, float, float, float]:
        """(v_x, v_y, v_z, y) of the root body now."""
        data: Any = self.env.unwrapped.data  # type: ignore[attr-defined]
        qpos, qvel = data.qpos, data.qvel
        if self.kind == "planar":
            return float(qvel[0]), 0.0, float(qvel[1]), 0.0
        return float(qvel[0]), float(qvel[1]), float(qvel[2]), float(qpos[1])

    def reward_now(self, action: NDArray[Any]) -> float:
        """The walking reward of the current state for ``action``."""
        v_x, v_y, v_z, y = self.root_state()
        u = np.clip(np.asarray(action, dtype=np.float64), self._low, self._high)
        return walking_reward(v_x, v_y, v_z, y, u, self.v_max)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        """Step the walker; the reward is the walking reward, the env's own in info."""
        obs, env_reward, terminated, truncated, info = self.env.step(action)
        info = dict(info)
        info["env_reward"] = float(env_reward)
        return obs, self.reward_now(action), terminated, truncated, info


def walking_vec_env(env_id: str, n_envs: int = 1, v_max: float = DEFAULT_V_MAX) -> VectorEnv:
    """``n_envs`` copies of the walker ``env_id`` under :class:`WalkingReward`.

    Raises:
        InvalidArgumentError: For an unsupported env id or v_max <= 0.
    """
    from policylab.deep.common.envs import make_env

    WalkingReward(make_env(env_id), v_max).close()  # a clear error before any copy is made
    fn: Callable[[], gym.Env[Any, Any]] = lambda: WalkingReward(make_env(env_id), v_max)  # noqa: E731
    return gym.vector.SyncVectorEnv([fn for _ in range(n_envs)])


def reward_description(envs: VectorEnv | None) -> dict[str, Any]:
    """Which reward the envs give: ``{"name": "walking", "v_max": V}`` or ``{"name": "env"}``."""
    if isinstance(envs, gym.vector.SyncVectorEnv) and envs.envs:
        env: Any = envs.envs[0]
        while isinstance(env, gym.Wrapper):
            if isinstance(env, WalkingReward):
                return {"name": "walking", "v_max": env.v_max}
            env = env.env
    return {"name": "env"}


REWARDS = ("env", "walking")
"""The rewards ``policylab train --reward`` offers: the env's own, or the walking reward."""


def reward_env(
    env_id: str, reward: dict[str, Any] | str, n_envs: int = 1, v_max: float | None = None
) -> str | VectorEnv:
    """The env to train or evaluate on for a reward: the id itself, or walking copies of it.

    Args:
        env_id: A Gymnasium id.
        reward: ``"env"``, ``"walking"``, or a :func:`reward_description` dict.
        n_envs: Number of copies (walking reward).
        v_max: The speed cap of the walking reward (default :data:`DEFAULT_V_MAX`).

    Raises:
        InvalidArgumentError: For an unknown reward, a v_max without the walking reward,
            or an env the walking reward cannot read.
    """
    if isinstance(reward, dict):
        name = reward.get("name", "env")
        v_max = reward.get("v_max", v_max)
    else:
        name = reward
    if name not in REWARDS:
        raise InvalidArgumentError(f"reward must be one of {', '.join(REWARDS)}; got {name!r}")
    if name == "env":
        if v_max is not None:
            raise InvalidArgumentError(
                "--v-max applies to the walking reward: add --reward walking"
            )
        return env_id
    return walking_vec_env(env_id, n_envs, DEFAULT_V_MAX if v_max is None else float(v_max))


def run_reward(run_json: str | Path) -> dict[str, Any]:
    """The reward a run folder's ``run.json`` records (``{"name": "env"}`` if none)."""
    p = Path(run_json)
    if not p.is_file():
        return {"name": "env"}
    try:
        doc = json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError):
        return {"name": "env"}
    reward = doc.get("reward") if isinstance(doc, dict) else None
    return reward if isinstance(reward, dict) else {"name": "env"}


def resume_env(run_dir: str | Path, env_id: str | None = None) -> VectorEnv | None:
    """The env to resume a run folder on (None: the agent re-makes it from its id).

    A run that trained on the walking reward resumes on walking copies of its env, as
    many as its ``n_envs``.
    """
    reward = run_reward(Path(run_dir) / "run.json")
    if reward.get("name") != "walking":
        return None
    doc = json.loads((Path(run_dir) / "run.json").read_text())
    env_id = doc.get("env_id") or env_id
    if env_id is None:
        return None
    n_envs = int(doc.get("config", {}).get("n_envs", 1))
    return walking_vec_env(env_id, n_envs, float(reward.get("v_max", DEFAULT_V_MAX)))


def evaluate_walking(
    agent: Any, run_json: str | Path, episodes: int, seed: int, deterministic: bool = True
) -> NDArray[np.float64] | None:
    """Returns of ``agent`` under the walking reward if its run trained on it, else None.

    The episodes are those of :func:`~policylab.deep.common.evaluation.evaluate` with the
    same seed (same number of envs, same resets), so with a deterministic policy each
    return pairs with the env-reward return of the same episode.
    """
    from policylab.deep.common.evaluation import evaluate

    reward = run_reward(run_json)
    if reward.get("name") != "walking" or agent.env_id is None:
        return None
    env = reward_env(agent.env_id, reward, n_envs=min(int(episodes), 16))
    return evaluate(agent, env, episodes=episodes, seed=seed, deterministic=deterministic)
