"""Returns (notes section 4.2): the discounted return G_t of an episode."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.validation import check_gamma

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["discounted_return", "returns_to_go"]


def _rewards_and_gamma(rewards: ArrayLike, gamma: float) -> tuple[NDArray[np.float64], float]:
    try:
        r = np.asarray(rewards, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidArgumentError(
            f"rewards must be a sequence of numbers; got {rewards!r}"
        ) from None
    if r.ndim != 1:
        raise InvalidArgumentError(
            f"rewards must be one-dimensional (R_1 .. R_T); got shape {r.shape}"
        )
    if not np.all(np.isfinite(r)):
        raise InvalidArgumentError("rewards must be finite")
    return r, check_gamma(gamma)


def returns_to_go(rewards: ArrayLike, gamma: float) -> NDArray[np.float64]:
    """The return at every step of an episode, computed backwards in one pass.

    G_t = R_{t+1} + gamma * G_{t+1}, with G_T = 0, so that
    G_t = R_{t+1} + gamma R_{t+2} + gamma^2 R_{t+3} + ...

    Args:
        rewards: R_1, ..., R_T of one episode.
        gamma: Discount rate in [0, 1].

    Returns:
        (T,) array [G_0, G_1, ..., G_{T-1}].
    """
    r, g = _rewards_and_gamma(rewards, gamma)
    out = np.empty_like(r)
    acc = 0.0
    for t in range(len(r) - 1, -1, -1):
        acc = r[t] + g * acc
        out[t] = acc
    return out


def discounted_return(rewards: ArrayLike, gamma: float) -> float:
    """G_0 = sum_{k=0}^{T-1} gamma^k R_{k+1}, the discounted return of one episode.

    Args:
        rewards: R_1, ..., R_T.
        gamma: Discount rate in [0, 1].
    """
    r, g = _rewards_and_gamma(rewards, gamma)
    acc = 0.0
    for x in r[::-1]:
        acc = float(x) + g * acc
    return acc
