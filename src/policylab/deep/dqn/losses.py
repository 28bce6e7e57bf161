"""The equations of DQN's update (Mnih et al. 2015; van Hasselt et al. 2016), one function each."""

from __future__ import annotations

import torch
from torch.nn import functional

__all__ = ["q_learning_targets", "td_error_grad", "td_loss", "td_loss_grad"]


def q_learning_targets(
    returns: torch.Tensor,
    discounts: torch.Tensor,
    next_q_target: torch.Tensor,
    next_q_online: torch.Tensor | None,
) -> torch.Tensor:
    """Bootstrapped (n-step) Q-learning targets y.

    DQN:        y = G_{t:t+n} + d * max_a Q_target(S', a)
    Double DQN: y = G_{t:t+n} + d * Q_target(S', argmax_a Q_online(S', a))

    with d = gamma^n (1 - terminated) the stored bootstrap weight (0 after a
    termination, gamma^n after a truncation or a step that did not end the episode).

    Args:
        returns: (B,) G_{t:t+n}.
        discounts: (B,) d.
        next_q_target: (B, A) Q_target(S', .).
        next_q_online: (B, A) Q_online(S', .) for Double DQN, or None for DQN.
    """
    if next_q_online is None:
        bootstrap = next_q_target.max(dim=1).values
    else:
        best = next_q_online.argmax(dim=1, keepdim=True)
        bootstrap = next_q_target.gather(1, best).squeeze(1)
    return returns + discounts * bootstrap


def td_loss(
    td_errors: torch.Tensor, weights: torch.Tensor | None, kind: str = "huber"
) -> torch.Tensor:
    """Importance-weighted mean of the Huber (smooth L1, delta 1) or squared TD error.

    ``weights`` None weighs every error by 1 (uniform replay).
    """
    zeros = torch.zeros_like(td_errors)
    per = (
        functional.smooth_l1_loss(td_errors, zeros, reduction="none")
        if kind == "huber"
        else td_errors**2
    )
    return (per if weights is None else weights * per).mean()


def td_loss_grad(
    td_errors: torch.Tensor, weights: torch.Tensor | None, kind: str = "huber"
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`td_loss` and its derivative dL/d delta_i over a batch of B TD errors.

    L = (1/B) sum_i w_i l(delta_i) with l the Huber loss (delta 1) or the square:

    Huber:   dL/d delta_i = w_i clip(delta_i, -1, 1) / B
    squared: dL/d delta_i = 2 w_i delta_i / B

    ``weights`` None is w_i = 1 (uniform replay), without the multiplications.
    """
    if kind == "huber":
        a = torch.clamp(td_errors, -1.0, 1.0).abs_()
        per = a * (td_errors.abs() - 0.5 * a)  # 0.5 d^2 inside [-1, 1], |d| - 0.5 outside
    else:
        per = td_errors * td_errors
    loss = (per if weights is None else weights * per).mean()
    return loss, td_error_grad(td_errors, weights, kind)


def td_error_grad(
    td_errors: torch.Tensor, weights: torch.Tensor | None, kind: str = "huber"
) -> torch.Tensor:
    """dL/d delta_i of :func:`td_loss` alone (the gradient step needs no loss value).

    Huber: w_i clip(delta_i, -1, 1) / B; squared: 2 w_i delta_i / B (``weights`` None
    is w_i = 1).
    """
    grad = torch.clamp(td_errors, -1.0, 1.0) if kind == "huber" else 2.0 * td_errors
    if weights is not None:
        grad.mul_(weights)
    return grad.mul_(1.0 / td_errors.numel())
