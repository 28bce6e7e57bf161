"""The equations of TD3 (Fujimoto et al. 2018), one function each.

The critics' clipped double-Q target and loss are shared with SAC
(:mod:`policylab.deep.common.losses`); what is TD3's own is here.
"""

from __future__ import annotations

import torch

__all__ = ["smoothed_target_actions", "td3_actor_loss", "td3_actor_loss_grad"]


def smoothed_target_actions(
    next_actions: torch.Tensor, noise: torch.Tensor, noise_clip: float
) -> torch.Tensor:
    """Target policy smoothing: A' = clip(mu'(S') + clip(eps, -c, c), -1, 1).

    Args:
        next_actions: (B, m) mu'(S') of the target actor, in [-1, 1].
        noise: (B, m) eps ~ N(0, sigma^2) (sigma is ``target_policy_noise``).
        noise_clip: c (``target_noise_clip``).
    """
    return (next_actions + noise.clamp(-noise_clip, noise_clip)).clamp(-1.0, 1.0)


def td3_actor_loss(q1: torch.Tensor) -> torch.Tensor:
    """The deterministic policy loss J = -E_{s ~ D}[ Q_1(s, mu(s)) ].

    Args:
        q1: (B,) Q_1(s, mu(s)) of the first critic.
    """
    return -q1.mean()


def td3_actor_loss_grad(q1: torch.Tensor) -> torch.Tensor:
    """The gradient of :func:`td3_actor_loss` in the critic's values: dJ/dQ_1(s_b, mu(s_b)) = -1/B.

    Args:
        q1: (..., B) Q_1(s, mu(s)).
    """
    return torch.full_like(q1, -1.0 / q1.shape[-1])
