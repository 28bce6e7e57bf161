"""The equations of Soft Actor-Critic (Haarnoja et al. 2018), one function each.

The critics' target and loss are shared with TD3
(:mod:`policylab.deep.common.losses`); what is SAC's own is here.
"""

from __future__ import annotations

import math

import torch
from torch.nn import functional

__all__ = ["entropy_coef_loss", "sac_actor_loss", "squashed_gaussian_log_prob"]

_LOG_2PI = math.log(2 * math.pi)
_LOG_2 = math.log(2.0)


def squashed_gaussian_log_prob(
    u: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor
) -> torch.Tensor:
    """Log-density log pi(a | s) of a = tanh(u), u ~ N(mean, exp(log_std)^2), per row.

    log pi(a | s) = sum_j [ log N(u_j; mean_j, std_j) - log(1 - tanh(u_j)^2) ],

    with log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)), exact and stable for
    large |u| (the change of variables of Haarnoja et al. 2018, appendix C).

    Args:
        u: (B, m) pre-squash samples.
        mean: (B, m) Gaussian means.
        log_std: (B, m) Gaussian log standard deviations.
    """
    z = (u - mean) * torch.exp(-log_std)
    gaussian = -0.5 * z**2 - log_std - 0.5 * _LOG_2PI
    log_det = 2.0 * (_LOG_2 - u - functional.softplus(-2.0 * u))
    return (gaussian - log_det).sum(dim=-1)


def sac_actor_loss(
    log_prob: torch.Tensor, q: torch.Tensor, alpha: float | torch.Tensor
) -> torch.Tensor:
    """The policy loss J_pi = E_{s ~ D, a ~ pi}[ alpha log pi(a | s) - min_i Q_i(s, a) ].

    Args:
        log_prob: (B,) log pi(a | s) of reparameterised actions a.
        q: (2, B) Q_1(s, a) and Q_2(s, a).
        alpha: The entropy temperature.
    """
    return (alpha * log_prob - q.min(dim=0).values).mean()


def entropy_coef_loss(
    log_alpha: torch.Tensor, log_prob: torch.Tensor, target_entropy: float
) -> torch.Tensor:
    """The temperature loss J(alpha) = -E[ log alpha * (log pi(a | s) + H_target) ].

    Its gradient raises alpha when the policy's entropy -E[log pi] is below the target
    H_target and lowers it above (Haarnoja et al. 2018b, eq. 18, written in log alpha
    as Stable-Baselines3 and CleanRL do, which keeps alpha positive).

    Args:
        log_alpha: () the learned log alpha.
        log_prob: (B,) log pi(a | s), held constant.
        target_entropy: H_target (-m, the action dimension, by default).
    """
    return -(log_alpha * (log_prob.detach() + target_entropy)).mean()
