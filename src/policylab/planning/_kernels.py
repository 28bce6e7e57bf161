"""Compiled in-place (Gauss-Seidel) sweeps over the MDP's outcome table (numba)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

__all__ = ["gauss_seidel_expectation_sweep", "gauss_seidel_optimality_sweep"]


@njit(cache=True, nogil=True)
def _gs_optimality(
    indptr: Any, nxt: Any, probs: Any, R: Any, mask: Any, terminal: Any, gamma: float, v: Any
) -> float:  # pragma: no cover - compiled
    S, A = R.shape
    delta = 0.0
    for s in range(S):
        if terminal[s]:
            continue
        best = -np.inf
        for a in range(A):
            if not mask[s, a]:
                continue
            row = s * A + a
            acc = 0.0
            for k in range(indptr[row], indptr[row + 1]):
                acc += probs[k] * v[nxt[k]]
            val = R[s, a] + gamma * acc
            if val > best:
                best = val
        d = abs(best - v[s])
        if d > delta:
            delta = d
        v[s] = best
    return delta


@njit(cache=True, nogil=True)
def _gs_expectation(
    indptr: Any, nxt: Any, probs: Any, R: Any, pi: Any, terminal: Any, gamma: float, v: Any
) -> float:  # pragma: no cover - compiled
    S, A = R.shape
    delta = 0.0
    for s in range(S):
        if terminal[s]:
            continue
        total = 0.0
        for a in range(A):
            w = pi[s, a]
            if w == 0.0:
                continue
            row = s * A + a
            acc = 0.0
            for k in range(indptr[row], indptr[row + 1]):
                acc += probs[k] * v[nxt[k]]
            total += w * (R[s, a] + gamma * acc)
        d = abs(total - v[s])
        if d > delta:
            delta = d
        v[s] = total
    return delta


def gauss_seidel_optimality_sweep(mdp: Any, gamma: float, v: np.ndarray) -> float:
    """One in-place sweep v(s) <- max_a [r(s, a) + gamma sum_s' p(s'|s, a) v(s')], s = 0..S-1.

    Later states already see the new values of earlier ones. Returns max_s |change|.
    """
    return float(
        _gs_optimality(
            mdp.indptr,
            mdp.next_states,
            mdp.probs,
            np.ascontiguousarray(mdp.expected_reward),
            mdp.action_mask,
            mdp.terminal,
            gamma,
            v,
        )
    )


def gauss_seidel_expectation_sweep(
    mdp: Any, probs: np.ndarray, gamma: float, v: np.ndarray
) -> float:
    """One in-place sweep v(s) <- sum_a pi(a|s) [r(s, a) + gamma sum_s' p(s'|s, a) v(s')].

    Returns max_s |change|.
    """
    return float(
        _gs_expectation(
            mdp.indptr,
            mdp.next_states,
            mdp.probs,
            np.ascontiguousarray(mdp.expected_reward),
            np.ascontiguousarray(probs),
            mdp.terminal,
            gamma,
            v,
        )
    )
