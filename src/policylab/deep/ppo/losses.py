"""The equations of PPO's loss (Schulman et al. 2017), one function each."""

from __future__ import annotations

import torch

__all__ = ["clipped_surrogate_loss", "normalized", "value_loss"]


def clipped_surrogate_loss(
    ratio: torch.Tensor, advantages: torch.Tensor, clip_range: float
) -> torch.Tensor:
    """The clipped policy objective, negated to be minimised.

    L^CLIP = -E[ min(r_t A_t, clip(r_t, 1 - eps, 1 + eps) A_t) ],
    r_t = pi(A_t | S_t) / pi_old(A_t | S_t).
    """
    unclipped = ratio * advantages
    clipped = torch.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range) * advantages
    return -torch.min(unclipped, clipped).mean()


def value_loss(
    values: torch.Tensor, old_values: torch.Tensor, returns: torch.Tensor, clip_range: float | None
) -> torch.Tensor:
    """The critic's squared error, optionally with PPO2's value clipping.

    L^V = E[(V(S_t) - G_t)^2], or with clipping
    L^V = E[max((V - G_t)^2, (V_old + clip(V - V_old, -c, c) - G_t)^2)].
    """
    err = (values - returns) ** 2
    if clip_range is None:
        return err.mean()
    clipped = old_values + torch.clamp(values - old_values, -clip_range, clip_range)
    return torch.max(err, (clipped - returns) ** 2).mean()


def normalized(x: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """(x - mean(x)) / (std(x) + eps): advantage normalisation within a minibatch."""
    if x.numel() < 2:
        return x
    return (x - x.mean()) / (x.std() + eps)
