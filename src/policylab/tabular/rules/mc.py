"""The Monte Carlo update rules (Sutton & Barto chapter 5), compiled with numba.

* :func:`episode_return`: G_0 = sum_k gamma^k R_{k+1} (S&B eq. 3.8, section 3.3).
* :func:`first_visit_flags`: which visits are first visits (section 5.1).
* :func:`mc_episode_update`: one finished episode, backwards: the incremental sample
  average Q <- Q + (G - Q) / N (S&B eq. 2.3, section 5.1), ordinary importance
  sampling (eq. 5.5, section 5.5), weighted importance sampling in its incremental
  form (eq. 5.8, section 5.6) and off-policy control of the greedy target
  (section 5.7).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numba as nb
import numpy as np
from numpy.typing import NDArray

from policylab.tabular.kernels import EpisodeBuffers, greedy_action
from policylab.tabular.schedules import schedule_value

__all__ = [
    "AVERAGE",
    "IS_CONTROL",
    "IS_PREDICTION",
    "MCScratch",
    "MCSettings",
    "MCTables",
    "episode_return",
    "first_visit_flags",
    "mc_episode_update",
]

#: Update kinds of :func:`mc_episode_update`.
AVERAGE, IS_PREDICTION, IS_CONTROL = 0, 1, 2


@nb.njit(cache=True, nogil=True)
def episode_return(rewards: NDArray[np.float64], T: int, gamma: float) -> float:  # pragma: no cover
    """G_0 = sum_{k=0}^{T-1} gamma^k R_{k+1} of the episode in ``rewards[:T]``."""
    g = 0.0
    for t in range(T - 1, -1, -1):
        g = rewards[t] + gamma * g
    return g


@nb.njit(cache=True, nogil=True)
def first_visit_flags(
    keys: NDArray[np.int64], T: int, mark: NDArray[np.int64], stamp: int, flags: NDArray[np.bool_]
) -> None:  # pragma: no cover - compiled
    """flags[t] = True iff keys[t] does not occur in keys[:t] (the first visit at time t).

    ``mark`` is a scratch array over all keys and ``stamp`` a number never used before
    with it (the episode number), so nothing needs clearing between episodes.
    """
    for t in range(T):
        k = keys[t]
        if mark[k] != stamp:
            mark[k] = stamp
            flags[t] = True
        else:
            flags[t] = False


class MCSettings(NamedTuple):
    """The fixed settings of a Monte Carlo run's updates.

    ``kind``: :data:`AVERAGE`, :data:`IS_PREDICTION` or :data:`IS_CONTROL`; ``alpha``
    the step-size schedule's params (1/n: sample averages); ``weighted``: weighted
    importance sampling; ``target``: pi(a | s) flat over s * A + a (IS prediction).
    """

    gamma: float
    kind: int
    first_visit: bool
    alpha: Any
    weighted: bool
    target: Any


class MCTables(NamedTuple):
    """A Monte Carlo run's tables, flat: ``q, nq, cq`` over s * A + a, ``v, nv, cv`` over s.

    Values, visit counts and cumulative importance weights; ``q`` is the (S, A) Q-table
    seen flat (a view).
    """

    q: Any
    nq: Any
    cq: Any
    v: Any
    nv: Any
    cv: Any


class MCScratch(NamedTuple):
    """Scratch of :func:`mc_episode_update`.

    Each step's key s * A + a, first-visit flags and the marks of
    :func:`first_visit_flags` (kept across episodes).
    """

    keys: Any
    flags_q: Any
    flags_v: Any
    mark_q: Any
    mark_v: Any


@nb.njit(cache=True, nogil=True)
def mc_episode_update(
    settings: MCSettings,
    tables: MCTables,
    buf: EpisodeBuffers,
    scratch: MCScratch,
    mask: NDArray[np.bool_],
    T: int,
    stamp: int,
) -> None:  # pragma: no cover - compiled
    """Update the tables from one finished episode, backwards from t = T - 1 to 0.

    G_t = R_{t+1} + gamma G_{t+1}. Flat tables: ``q, nq, cq`` over s * A + a and
    ``v, nv, cv`` over s (values, visit counts, cumulative importance weights).

    * ``AVERAGE`` (on-policy): N <- N + 1; Q(S_t, A_t) <- Q + alpha_N (G_t - Q), and
      the same for V(S_t); alpha_N = schedule ``alpha`` at N (1/N: sample average).
    * ``IS_PREDICTION``: rho_t = pi(A_t | S_t) / b(A_t | S_t); W_t = prod_{k=t+1}^{T-1}
      rho_k for Q(S_t, A_t) and rho_t W_t for V(S_t). Ordinary importance sampling:
      N <- N + 1, Q <- Q + (W G_t - Q) / N, the mean of W G over all visits. Weighted:
      C <- C + W, Q <- Q + (W / C)(G_t - Q), i.e. sum W G / sum W.
    * ``IS_CONTROL``: the same for the greedy target pi(s) = argmax_a Q(s, a) (updated
      as it goes, Sutton & Barto section 5.7): after updating Q(S_t, A_t), W becomes 0
      (weighted: stop) if A_t is not greedy, else W <- W / b(A_t | S_t).

    With ``first_visit`` only the first visit of a key in the episode is used.
    """
    gamma, kind, first_visit = settings.gamma, settings.kind, settings.first_visit
    alpha, weighted, target = settings.alpha, settings.weighted, settings.target
    q, nq, cq, v, nv, cv = tables
    buf_s, buf_a, buf_r, buf_b = buf
    keys, flags_q, flags_v, mark_q, mark_v = scratch
    n_actions = mask.shape[1]
    for t in range(T):
        keys[t] = buf_s[t] * n_actions + buf_a[t]
    if first_visit:
        first_visit_flags(keys, T, mark_q, stamp, flags_q)
        first_visit_flags(buf_s, T, mark_v, stamp, flags_v)
    g = 0.0
    w = 1.0
    for t in range(T - 1, -1, -1):
        g = buf_r[t] + gamma * g
        s = buf_s[t]
        k = keys[t]
        use_q = (not first_visit) or flags_q[t]
        use_v = (not first_visit) or flags_v[t]
        if kind == AVERAGE:
            if use_q:
                nq[k] += 1.0
                q[k] += schedule_value(alpha, nq[k]) * (g - q[k])
            if use_v:
                nv[s] += 1.0
                v[s] += schedule_value(alpha, nv[s]) * (g - v[s])
            continue
        rho = target[k] / buf_b[t] if kind == IS_PREDICTION else 0.0
        w_v = w * rho
        if use_q:
            nq[k] += 1.0
            if weighted:
                if w > 0.0:
                    cq[k] += w
                    q[k] += (w / cq[k]) * (g - q[k])
            else:
                q[k] += (w * g - q[k]) / nq[k]
        if kind == IS_PREDICTION and use_v:
            nv[s] += 1.0
            if weighted:
                if w_v > 0.0:
                    cv[s] += w_v
                    v[s] += (w_v / cv[s]) * (g - v[s])
            else:
                v[s] += (w_v * g - v[s]) / nv[s]
        if kind == IS_CONTROL:
            row = q[s * n_actions : (s + 1) * n_actions]
            if buf_a[t] == greedy_action(row, mask[s]):
                rho = 1.0 / buf_b[t]
        w *= rho
        if weighted and w == 0.0:
            break
