"""Deep RL with PyTorch: DQN, PPO, SAC and TD3 on any Gymnasium environment.

Imported lazily (``import policylab`` does not import torch; ``policylab.deep`` does)::

    import policylab as pl
    agent = pl.deep.PPO("CartPole-v1", n_envs=8, n_steps=32, batch_size=256)
    agent.learn(100_000, progress=True)
    returns = pl.deep.evaluate(agent, episodes=100, seed=0)
    agent.save("ppo.pt"); agent = pl.deep.PPO.load("ppo.pt")
"""

from __future__ import annotations

from policylab.deep.common import (
    MLP,
    Agent,
    NatureCNN,
    ObservationNormalizer,
    PrioritizedReplayBuffer,
    ReplayBuffer,
    RewardScaler,
    RolloutBuffer,
    RunLogger,
    RunningMeanStd,
    TrainingProgress,
    evaluate,
    gae_advantages,
    load_checkpoint,
    make_env,
    make_vec_env,
    n_step_targets,
    save_checkpoint,
)
from policylab.deep.common.walking import WalkingReward, walking_reward, walking_vec_env
from policylab.deep.dqn import DQN, DQNConfig
from policylab.deep.io import load
from policylab.deep.ppo import PPO, PPOConfig
from policylab.deep.sac import SAC, SACConfig
from policylab.deep.td3 import TD3, TD3Config
from policylab.deep.zoo import ALGORITHMS, default_config

__all__ = [
    "ALGORITHMS",
    "DQN",
    "MLP",
    "PPO",
    "SAC",
    "TD3",
    "Agent",
    "DQNConfig",
    "NatureCNN",
    "ObservationNormalizer",
    "PPOConfig",
    "PrioritizedReplayBuffer",
    "ReplayBuffer",
    "RewardScaler",
    "RolloutBuffer",
    "RunLogger",
    "RunningMeanStd",
    "SACConfig",
    "TD3Config",
    "TrainingProgress",
    "WalkingReward",
    "default_config",
    "evaluate",
    "gae_advantages",
    "load",
    "load_checkpoint",
    "make_env",
    "make_vec_env",
    "n_step_targets",
    "save_checkpoint",
    "walking_reward",
    "walking_vec_env",
]
