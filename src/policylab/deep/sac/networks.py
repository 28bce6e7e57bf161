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
        return self.split(self.features(obs))

    @staticmethod
    def split(features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(mu, log sigma) from the MLP's (B, 2m) outputs, log sigma clipped to [-20, 2]."""
        mean, log_std = features.chunk(2, dim=-1)
        return mean, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def sample(
        self, obs: torch.Tensor, generator: torch.Generator | None, log_prob: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Reparameterised actions a = tanh(mu + sigma eps), eps ~ N(0, I), and log pi(a | s).

        The log-probability is None with ``log_prob=False`` (acting does not need it).
        """
        features = self.features(obs)
        if log_prob:
            action, logp, _, _ = self.reparameterised(features, generator)
            return action, logp
        mean, log_std = self.split(features)
        return torch.tanh(mean + log_std.exp() * torch.randn(mean.shape, generator=generator)), None

    @classmethod
    def reparameterised(
        cls, features: torch.Tensor, generator: torch.Generator | None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """:meth:`sample` from the MLP's (B, 2m) outputs, with what its gradient needs.

        Returns:
            a (B, m); log pi(a | s) (B,); the noise sigma eps (B, m); and (B, m) whether
            each raw log sigma lies inside the clipping range (where it has a gradient).
        """
        mean, raw = features.chunk(2, dim=-1)
        log_std = raw.clamp(LOG_STD_MIN, LOG_STD_MAX)
        noise = log_std.exp() * torch.randn(mean.shape, generator=generator)
        u = mean + noise
        in_range = log_std == raw  # clipping leaves exactly these unchanged
        return torch.tanh(u), squashed_gaussian_log_prob(u, mean, log_std), noise, in_range

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """The deterministic action tanh(mu(s)), (B, m)."""
        return torch.tanh(self.distribution(obs)[0])
