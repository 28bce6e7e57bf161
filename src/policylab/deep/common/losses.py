"""The equations the off-policy actor-critics (SAC, TD3) share, one function each.

Both learn twin critics Q_1, Q_2 by regression onto a target built from the smaller of
two target critics (clipped double Q-learning, Fujimoto et al. 2018), and both move
their target networks by Polyak averaging.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch.nn import functional

__all__ = ["clipped_double_q_targets", "polyak_update", "twin_q_loss", "twin_q_loss_grad"]


def clipped_double_q_targets(
    rewards: torch.Tensor,
    discounts: torch.Tensor,
    next_q: torch.Tensor,
    next_log_prob: torch.Tensor | None = None,
    alpha: float | torch.Tensor = 0.0,
) -> torch.Tensor:
    """Targets y of the twin critics.

    TD3: y = r + d * min_i Q'_i(S', A')
    SAC: y = r + d * (min_i Q'_i(S', A') - alpha * log pi(A' | S'))

    with A' the target policy's action at S' and d = gamma (1 - terminated) the stored
    bootstrap weight (0 after a termination, gamma after a truncation or a step that
    did not end the episode).

    Args:
        rewards: (B,) r.
        discounts: (B,) d.
        next_q: (2, B) Q'_1(S', A') and Q'_2(S', A') of the target critics.
        next_log_prob: (B,) log pi(A' | S') for SAC's soft target, or None for TD3.
        alpha: The entropy temperature (SAC).
    """
    bootstrap = next_q.amin(dim=0)
    if next_log_prob is not None:
        bootstrap = bootstrap - alpha * next_log_prob
    return rewards + discounts * bootstrap


def twin_q_loss(q: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """The twin critics' regression loss, summed over the two critics.

    L(phi_1, phi_2) = sum_{i=1,2} E[(Q_i(S, A) - y)^2] / 2

    (the one-half of Haarnoja et al. 2018's J_Q; Stable-Baselines3 writes the same
    loss as 0.5 * sum of the mean squared errors).

    Args:
        q: (2, B) Q_1(S, A) and Q_2(S, A).
        targets: (B,) y, held constant.
    """
    # the same number in one kernel: with two critics, sum_i mean_b / 2 = mean over (i, b)
    return functional.mse_loss(q, targets.unsqueeze(0).expand_as(q))


def twin_q_loss_grad(q: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """The gradient of :func:`twin_q_loss` with respect to the critics' values.

    dL/dQ_i(s_b, a_b) = (Q_i(s_b, a_b) - y_b) / B

    Args:
        q: (2, B) Q_1(S, A) and Q_2(S, A).
        targets: (B,) y, held constant.
    """
    return (q - targets.unsqueeze(0)) / q.shape[1]


@torch.no_grad()
def polyak_update(
    target: Sequence[torch.Tensor], online: Sequence[torch.Tensor], tau: float
) -> None:
    """theta_target <- tau * theta + (1 - tau) * theta_target, for every pair, in place."""
    torch._foreach_lerp_(list(target), list(online), tau)
