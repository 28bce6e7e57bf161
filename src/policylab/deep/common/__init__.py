"""The parts every deep agent shares: networks, buffers, envs, checkpoints, logs, evaluation."""

from policylab.deep.common.agent import Agent, BaseConfig
from policylab.deep.common.buffers import (
    NStepWindow,
    PrioritizedReplayBuffer,
    ReplayBatch,
    ReplayBuffer,
    RolloutBuffer,
)
from policylab.deep.common.checkpoint import atomic_write_bytes, load_checkpoint, save_checkpoint
from policylab.deep.common.envs import make_env, make_vec_env
from policylab.deep.common.evaluation import evaluate, run_episodes
from policylab.deep.common.logging import RunLogger, TrainingProgress
from policylab.deep.common.networks import MLP, NatureCNN
from policylab.deep.common.normalize import ObservationNormalizer, RewardScaler, RunningMeanStd
from policylab.deep.common.returns import gae_advantages, n_step_targets

__all__ = [
    "MLP",
    "Agent",
    "BaseConfig",
    "NStepWindow",
    "NatureCNN",
    "ObservationNormalizer",
    "PrioritizedReplayBuffer",
    "ReplayBatch",
    "ReplayBuffer",
    "RewardScaler",
    "RolloutBuffer",
    "RunLogger",
    "RunningMeanStd",
    "TrainingProgress",
    "atomic_write_bytes",
    "evaluate",
    "gae_advantages",
    "load_checkpoint",
    "make_env",
    "make_vec_env",
    "n_step_targets",
    "run_episodes",
    "save_checkpoint",
]
