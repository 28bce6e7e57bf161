"""Soft Actor-Critic for bounded continuous action spaces."""

from policylab.deep.sac.agent import SAC, SACConfig

__all__ = ["SAC", "SACConfig"]
