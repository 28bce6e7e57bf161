"""TD3's actor: a deterministic policy mu(s) in [-1, 1]^m."""

from __future__ import annotations

import torch

from policylab.deep.common.networks import ActorMLP

__all__ = ["DeterministicActor"]


class DeterministicActor(ActorMLP):
    """mu(s) = tanh(MLP(s)), (B, m); constructed as :class:`ActorMLP` with one head."""

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """mu(s) for a batch."""
        return torch.tanh(self.features(obs))
