"""PPO family: clipped objective, GAE, discrete and Gaussian policies."""

from policylab.deep.ppo.agent import PPO, PPOConfig
from policylab.deep.ppo.losses import clipped_surrogate_loss, normalized, value_loss
from policylab.deep.ppo.networks import ActorCritic

__all__ = ["PPO", "ActorCritic", "PPOConfig", "clipped_surrogate_loss", "normalized", "value_loss"]
