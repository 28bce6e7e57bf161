"""TD3's actor: a deterministic policy mu(s) in [-1, 1]^m."""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from policylab.deep.common.networks import MLP

__all__ = ["DeterministicActor"]


class DeterministicActor(nn.Module):
    """mu(s) = tanh(MLP(s)), (B, m).

    Args:
        obs_dim: Observation features.
        action_dim: m, the action dimensions.
        hidden: Hidden layer sizes.
        act: Activation name (tanh, relu, elu).
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        hidden: Sequence[int],
        act: str = "relu",
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        self.net = MLP(obs_dim, hidden, action_dim, act, out_gain=0.01, generator=generator)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """mu(s) for a batch."""
        return torch.tanh(self.net(obs.reshape(len(obs), -1)))
