"""TD3 (Twin Delayed DDPG) for bounded continuous action spaces."""

from policylab.deep.td3.agent import TD3, TD3Config

__all__ = ["TD3", "TD3Config"]
