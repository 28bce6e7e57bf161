"""The equations of PPO's loss (Schulman et al. 2017), one function each."""

from __future__ import annotations

import torch

__all__ = [
    "approx_kl",
    "clipped_surrogate_loss",
    "clipped_surrogate_loss_grad",
    "normalized",
    "value_loss",
    "value_loss_grad",
]


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


def approx_kl(ratio: torch.Tensor, log_ratio: torch.Tensor) -> torch.Tensor:
    """An estimate of KL(pi_old || pi) from the sampled steps' probability ratios.

    KL ~ E[(r_t - 1) - log r_t], r_t = pi(A_t | S_t) / pi_old(A_t | S_t), over the steps
    the old policy sampled: unbiased and never negative (log x <= x - 1). In float64.
    """
    with torch.no_grad():
        return ((ratio.double() - 1) - log_ratio.double()).mean()


def normalized(x: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """(x - mean(x)) / (std(x) + eps): advantage normalisation within a minibatch."""
    if x.numel() < 2:
        return x
    return (x - x.mean()) / (x.std() + eps)


# ---------------------------------------------------------------------------
# The same losses with their gradients written out, for the hand-written backward
# pass of small MLPs (policylab.deep.common.mlp_grad). Each returns the loss and its
# derivative with respect to its first argument, as autograd would compute it
# (torch.min/max split a tie's gradient in halves; clamp passes it on [lo, hi]).
# ---------------------------------------------------------------------------


def clipped_surrogate_loss_grad(
    ratio: torch.Tensor, advantages: torch.Tensor, clip_range: float
) -> tuple[torch.Tensor, torch.Tensor]:
    """L^CLIP of :func:`clipped_surrogate_loss` and dL^CLIP/dr_t over a batch of B steps.

    dL^CLIP/dr_t = -A_t / B where r_t A_t <= clip(r_t, 1 - eps, 1 + eps) A_t, else 0:
    the gradient flows through the unclipped term where it is the minimum; where the
    clipped term is strictly smaller, r_t lies outside [1 - eps, 1 + eps] and the clip
    passes no gradient (a tie inside the range gives half through each term, A_t / B
    in all).
    """
    n = ratio.numel()
    unclipped = ratio * advantages
    clipped = torch.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range) * advantages
    loss = -torch.min(unclipped, clipped).mean()
    grad = (advantages * (unclipped <= clipped)).mul_(-1.0 / n)
    return loss, grad


def value_loss_grad(
    values: torch.Tensor, old_values: torch.Tensor, returns: torch.Tensor, clip_range: float | None
) -> tuple[torch.Tensor, torch.Tensor]:
    """L^V of :func:`value_loss` and dL^V/dV(S_t) over a batch of B steps.

    Unclipped: dL^V/dV = 2 (V - G_t) / B. Clipped, with V^c = V_old + clip(V - V_old, -c, c):
    2 (V - G_t) / B where (V - G_t)^2 is the larger error, 2 (V^c - G_t) / B where
    (V^c - G_t)^2 is (zero when V - V_old is outside [-c, c]), half of each on a tie.
    """
    n = values.numel()
    err = values - returns
    if clip_range is None:
        sq = err * err
        return sq.mean(), err * (2.0 / n)
    d = values - old_values
    err_c = old_values + torch.clamp(d, -clip_range, clip_range) - returns
    sq, sq_c = err * err, err_c * err_c
    tie = 0.5 * (sq == sq_c)
    w = (sq > sq_c) + tie
    w_c = ((sq_c > sq) + tie) * (d.abs() <= clip_range)
    return torch.max(sq, sq_c).mean(), (w * err + w_c * err_c) * (2.0 / n)
