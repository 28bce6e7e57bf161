"""SAC's actor: a tanh-squashed diagonal Gaussian policy."""

from __future__ import annotations

from collections.abc import Sequence

import torch

from policylab.deep.common.networks import ActorMLP
from policylab.deep.sac.losses import squashed_gaussian_log_prob

__all__ = ["LOG_STD_MAX", "LOG_STD_MIN", "SquashedGaussianActor"]

LOG_STD_MIN, LOG_STD_MAX = -20.0, 2.0
"""The range log std is clipped to (as in Stable-Baselines3)."""


class SquashedGaussianActor(ActorMLP):
    """pi(. | s): a = tanh(u), u ~ N(mu(s), diag(sigma(s)^2)), a in (-1, 1)^m.

    One MLP outputs mu and log sigma together (one matrix product for both heads);
    constructed as :class:`ActorMLP` (whose ``heads`` is fixed to 2 here).
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        hidden: Sequence[int],
        act: str = "relu",
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__(obs_dim, action_dim, hidden, act, generator, heads=2)

    def distribution(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mu, log sigma) for a batch, each (B, m), log sigma clipped to [-20, 2]."""
        mean, log_std = self.features(obs).chunk(2, dim=-1)
        return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def sample(
        self, obs: torch.Tensor, generator: torch.Generator | None, log_prob: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Reparameterised actions a = tanh(mu + sigma eps), eps ~ N(0, I), and log pi(a | s).

        The log-probability is None with ``log_prob=False`` (acting does not need it).
        """
        mean, log_std = self.distribution(obs)
        u = mean + log_std.exp() * torch.randn(mean.shape, generator=generator)
        return torch.tanh(u), squashed_gaussian_log_prob(u, mean, log_std) if log_prob else None

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """The deterministic action tanh(mu(s)), (B, m)."""
        return torch.tanh(self.distribution(obs)[0])
