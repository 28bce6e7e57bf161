"""Small environments for the deep RL tests."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np


class CountingEnv(gym.Env[np.ndarray, int]):
    """Observation [t] (the step count), reward 1 per step; terminates at ``terminate_at``."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, terminate_at: int | None = None) -> None:
        self.observation_space = gym.spaces.Box(0.0, 1000.0, shape=(1,), dtype=np.float32)
        self.action_space = gym.spaces.Discrete(2)
        self.terminate_at = terminate_at
        self.t = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.t = 0
        return np.array([0.0], dtype=np.float32), {}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        terminated = self.terminate_at is not None and self.t >= self.terminate_at
        return np.array([float(self.t)], dtype=np.float32), 1.0, terminated, False, {}


def counting_vec_env(
    n_envs: int = 2, limit: int = 5, terminate_at: int | None = None
) -> gym.vector.VectorEnv:
    return gym.vector.SyncVectorEnv(
        [
            lambda: gym.wrappers.TimeLimit(CountingEnv(terminate_at), max_episode_steps=limit)
            for _ in range(n_envs)
        ]
    )
