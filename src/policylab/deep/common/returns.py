"""Return targets of deep RL: generalised advantage estimates and n-step returns.

Both treat the two ways an episode can end as the design asks: ``terminated`` (the
MDP reached a terminal state, whose value is 0: no bootstrap) and ``truncated`` (a time
limit cut the episode: the value of the state it was cut in is bootstrapped).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from policylab.exceptions import InvalidArgumentError

__all__ = ["gae_advantages", "n_step_targets"]


def _check_unit(name: str, x: float) -> float:
    x = float(x)
    if not 0.0 <= x <= 1.0:
        raise InvalidArgumentError(f"{name} must be in [0, 1]; got {x!r}")
    return x


def gae_advantages(
    rewards: ArrayLike,
    values: ArrayLike,
    next_values: ArrayLike,
    terminated: ArrayLike,
    truncated: ArrayLike,
    gamma: float,
    gae_lambda: float,
) -> NDArray[np.float64]:
    """Generalised advantage estimates A_t (Schulman et al. 2016), along axis 0 (time).

    delta_t = R_{t+1} + gamma (1 - terminated_t) V(S'_t) - V(S_t)
    A_t     = delta_t + gamma lambda (1 - done_t) A_{t+1},   done_t = terminated_t or truncated_t

    S'_t is the state the step from S_t really reached (for a truncated step, the state
    the episode was cut in, whose value is bootstrapped; for a terminated step it does
    not matter). The recursion stops at every episode end, so advantages never leak
    from one episode into the next. lambda = 1 gives the Monte Carlo advantage G_t - V(S_t)
    (bootstrapped at truncation); lambda = 0 the one-step TD error.

    Args:
        rewards: (T, ...) R_{t+1}.
        values: (T, ...) V(S_t).
        next_values: (T, ...) V(S'_t).
        terminated: (T, ...) bool, the step reached a terminal state.
        truncated: (T, ...) bool, a time limit ended the episode after the step.
        gamma: Discount rate in [0, 1].
        gae_lambda: lambda in [0, 1].

    Returns:
        (T, ...) float64 advantages; the value targets are ``advantages + values``.
    """
    g, lam = _check_unit("gamma", gamma), _check_unit("gae_lambda", gae_lambda)
    r = np.asarray(rewards, dtype=np.float64)
    arrays = {
        "values": np.asarray(values, dtype=np.float64),
        "next_values": np.asarray(next_values, dtype=np.float64),
        "terminated": np.asarray(terminated, dtype=bool),
        "truncated": np.asarray(truncated, dtype=bool),
    }
    for name, a in arrays.items():
        if a.shape != r.shape:
            raise InvalidArgumentError(
                f"{name} must have the shape of rewards {r.shape}; got {a.shape}"
            )
    term, trunc = arrays["terminated"], arrays["truncated"]
    delta = r + g * (~term) * arrays["next_values"] - arrays["values"]
    carry = g * lam * ~(term | trunc)
    adv = np.empty_like(r)
    acc = np.zeros(r.shape[1:])
    for t in range(r.shape[0] - 1, -1, -1):
        acc = delta[t] + carry[t] * acc
        adv[t] = acc
    return adv


def n_step_targets(
    rewards: ArrayLike,
    terminated: ArrayLike,
    truncated: ArrayLike,
    gamma: float,
    n: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The n-step return of every step of one trajectory, cut at episode ends.

    G_{t:t+m} = R_{t+1} + gamma R_{t+2} + ... + gamma^{m-1} R_{t+m}
    target_t  = G_{t:t+m} + gamma^m (1 - terminated_{t+m-1}) max_a Q(S'_{t+m-1}, a)

    with m = min(n, steps to the end of the episode, steps left in the array): the
    sum stops at the first step that ends the episode (terminated or truncated) and
    only a termination removes the bootstrap term.

    Args:
        rewards: (T,) R_{t+1} of consecutive steps.
        terminated: (T,) bool.
        truncated: (T,) bool.
        gamma: Discount rate in [0, 1].
        n: Number of steps, at least 1.

    Returns:
        ``(returns, discounts, last)``: G_{t:t+m}; the bootstrap weight
        gamma^m (1 - terminated_{t+m-1}); and t+m-1, the step whose next state S' is
        bootstrapped from.
    """
    g = _check_unit("gamma", gamma)
    if int(n) != n or n < 1:
        raise InvalidArgumentError(f"n must be an integer >= 1; got {n!r}")
    r = np.asarray(rewards, dtype=np.float64)
    term = np.asarray(terminated, dtype=bool)
    done = term | np.asarray(truncated, dtype=bool)
    if r.ndim != 1 or term.shape != r.shape or done.shape != r.shape:
        raise InvalidArgumentError(
            f"rewards, terminated and truncated must be one-dimensional of one length; got "
            f"{r.shape}, {term.shape}, {done.shape}"
        )
    T = r.shape[0]
    returns = np.zeros(T)
    discounts = np.zeros(T)
    last = np.zeros(T, dtype=np.int64)
    for t in range(T):
        acc, w, k = 0.0, 1.0, t
        while True:
            acc += w * r[k]
            w *= g
            if done[k] or k - t + 1 == n or k == T - 1:
                break
            k += 1
        returns[t], discounts[t], last[t] = acc, (0.0 if term[k] else w), k
    return returns, discounts, last
