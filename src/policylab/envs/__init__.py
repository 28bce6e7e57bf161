"""Gymnasium environments backed by a FiniteMDP, and rollouts of episodes."""

from __future__ import annotations

import gymnasium as gym

from policylab.envs.mdp_env import MDPEnv, make_problem_env
from policylab.envs.rollout import Episode, rollout

__all__ = ["Episode", "MDPEnv", "make_problem_env", "register_envs", "rollout"]


def register_envs() -> list[str]:
    """Register ``policylab/<Name>-v0`` for every built-in problem; return the ids."""
    from policylab.problems.registry import list_problems

    ids = []
    for spec in list_problems():
        if spec.gym_id not in gym.envs.registry:
            gym.register(
                id=spec.gym_id,
                entry_point="policylab.envs.mdp_env:make_problem_env",
                kwargs={"problem": spec.name},
                disable_env_checker=True,
            )
        ids.append(spec.gym_id)
    return ids
