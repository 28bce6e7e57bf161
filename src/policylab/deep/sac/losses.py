"""The equations of Soft Actor-Critic (Haarnoja et al. 2018), one function each.

The critics' target and loss are shared with TD3
(:mod:`policylab.deep.common.losses`); what is SAC's own is here.
"""

from __future__ import annotations

import math

import torch
from torch.nn import functional

__all__ = [
    "entropy_coef_loss",
    "entropy_coef_loss_grad",
    "sac_actor_loss",
    "sac_actor_loss_grad",
    "squashed_gaussian_grad",
    "squashed_gaussian_log_prob",
]

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


def squashed_gaussian_grad(
    action: torch.Tensor,
    noise: torch.Tensor,
    grad_action: torch.Tensor,
    grad_log_prob: torch.Tensor,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Backpropagate through a reparameterised sample and its :func:`squashed_gaussian_log_prob`.

    For a = tanh(u), u = mean + sigma eps (sigma = exp(log_std), eps fixed) and
    log pi(a | s) of the change of variables, a loss L with upstream gradients
    dL/da and dL/dlog pi has

        dL/du = dL/da (1 - a^2) + dL/dlog pi * 2 a,
        dL/dmean = dL/du,
        dL/dlog_std = dL/du * sigma eps - dL/dlog pi,

    since the Gaussian term -z^2 / 2 - log_std - log(2 pi) / 2 has z = (u - mean) /
    sigma = eps whatever mean and log_std are (only -log_std moves), and
    d/du [-log(1 - tanh(u)^2)] = 2 tanh(u).

    Args:
        action: (B, m) a = tanh(u).
        noise: (B, m) sigma eps.
        grad_action: (B, m) dL/da.
        grad_log_prob: (B,) dL/dlog pi(a | s).

    Returns:
        (dL/dmean, dL/dlog_std), each (B, m).
    """
    g_lp = grad_log_prob.unsqueeze(-1)
    grad_u = grad_action * (1.0 - action * action) + 2.0 * g_lp * action
    return grad_u, grad_u * noise - g_lp


def sac_actor_loss(
    log_prob: torch.Tensor, q: torch.Tensor, alpha: float | torch.Tensor
) -> torch.Tensor:
    """The policy loss J_pi = E_{s ~ D, a ~ pi}[ alpha log pi(a | s) - min_i Q_i(s, a) ].

    Args:
        log_prob: (B,) log pi(a | s) of reparameterised actions a.
        q: (2, B) Q_1(s, a) and Q_2(s, a).
        alpha: The entropy temperature.
    """
    # amin: its backward is a mask (min's scatters into zeros, several times slower)
    return (alpha * log_prob - q.amin(dim=0)).mean()


def sac_actor_loss_grad(
    log_prob: torch.Tensor, q: torch.Tensor, alpha: float | torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The gradient of :func:`sac_actor_loss` with respect to log pi and the critics' values.

    dJ/dlog pi(a_b | s_b) = alpha / B;  dJ/dQ_i(s_b, a_b) = -1 / B for the smaller of
    the two values (the first on a tie), 0 for the other.

    Args:
        log_prob: (B,) log pi(a | s).
        q: (2, B) Q_1(s, a) and Q_2(s, a).
        alpha: The entropy temperature.

    Returns:
        (dJ/dlog pi, (B,); dJ/dQ, (2, B)).
    """
    b = q.shape[1]
    first = q[0] <= q[1]
    grad_q = torch.stack([first, ~first]).to(q.dtype) * (-1.0 / b)
    return torch.full_like(log_prob, 1.0 / b) * alpha, grad_q


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


def entropy_coef_loss_grad(log_prob: torch.Tensor, target_entropy: float) -> torch.Tensor:
    """The gradient of :func:`entropy_coef_loss` in log alpha: -E[ log pi(a | s) + H_target ].

    Args:
        log_prob: (B,) log pi(a | s).
        target_entropy: H_target.
    """
    return -(log_prob.mean() + target_entropy)
