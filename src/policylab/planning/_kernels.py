"""Compiled sweeps over the MDP's outcome table (numba).

Each kernel reads the outcomes of p(s' | s, a) straight from ``mdp.indptr``,
``mdp.next_states`` and ``mdp.probs`` in one pass, like a bare sparse matrix-vector
product, without building the (S * A, S) matrix or any (S, A) temporary. Indices are
read as unsigned integers so that no negative-index wraparound check is compiled in.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "gauss_seidel_expectation_sweep",
    "gauss_seidel_optimality_sweep",
    "optimality_sweep",
    "policy_matvec",
    "q_values",
]


#: Reassociation for the sums, but no "no-inf/no-nan" assumptions (-inf marks A(s)).
_FAST = {"reassoc", "contract", "arcp", "nsz"}


@njit(cache=True, nogil=True, fastmath=_FAST)
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
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                acc += probs[k] * v[np.uint64(nxt[k])]
            val = R[s, a] + gamma * acc
            if val > best:
                best = val
        d = abs(best - v[s])
        if d > delta:
            delta = d
        v[s] = best
    return delta


@njit(cache=True, nogil=True, fastmath=_FAST)
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
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                acc += probs[k] * v[np.uint64(nxt[k])]
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


@njit(cache=True, nogil=True, fastmath=_FAST)
def _q_values(
    indptr: Any, nxt: Any, probs: Any, R: Any, mask: Any, gamma: float, v: Any, q: Any
) -> None:  # pragma: no cover - compiled
    S, A = R.shape
    for s in range(S):
        for a in range(A):
            if not mask[s, a]:
                q[s, a] = -np.inf
                continue
            row = s * A + a
            acc = 0.0
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                acc += probs[k] * v[np.uint64(nxt[k])]
            q[s, a] = R[s, a] + gamma * acc


@njit(cache=True, nogil=True, fastmath=_FAST)
def _optimality_sweep(
    indptr: Any,
    nxt: Any,
    probs: Any,
    R: Any,
    mask: Any,
    terminal: Any,
    gamma: float,
    v: Any,
    out: Any,
    act: Any,
) -> None:  # pragma: no cover
    S, A = R.shape
    for s in range(S):
        if terminal[s]:
            out[s] = 0.0
            act[s] = -1
            continue
        best = -np.inf
        best_a = -1
        for a in range(A):
            if not mask[s, a]:
                continue
            row = s * A + a
            acc = 0.0
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                acc += probs[k] * v[np.uint64(nxt[k])]
            val = R[s, a] + gamma * acc
            if val > best:
                best = val
                best_a = a
        out[s] = best
        act[s] = best_a


@njit(cache=True, nogil=True, fastmath=_FAST)
def _policy_matvec(
    indptr: Any, nxt: Any, probs: Any, n_actions: int, act: Any, terminal: Any, x: Any, out: Any
) -> None:  # pragma: no cover - compiled
    S = terminal.shape[0]
    for s in range(S):
        if terminal[s]:
            out[s] = 0.0
            continue
        row = s * n_actions + act[s]
        acc = 0.0
        for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
            acc += probs[k] * x[np.uint64(nxt[k])]
        out[s] = acc


def q_values(mdp: Any, gamma: float, v: np.ndarray) -> np.ndarray:
    """q(s, a) = r(s, a) + gamma sum_s' p(s'|s, a) v(s'), -inf where a is not in A(s)."""
    q = np.empty((mdp.n_states, mdp.n_actions))
    _q_values(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        _reward(mdp),
        mdp.action_mask,
        gamma,
        np.ascontiguousarray(v, dtype=np.float64),
        q,
    )
    return q


def optimality_sweep(mdp: Any, gamma: float, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One synchronous Bellman optimality sweep in a single pass over the outcome table.

    Returns ``(T v, greedy action indices)`` (0 and -1 on terminal states). Reads each
    outcome once, like a bare sparse matrix-vector product, and allocates no (S, A) array.
    """
    out = np.empty(mdp.n_states)
    act = np.empty(mdp.n_states, dtype=np.int64)
    _optimality_sweep(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        _reward(mdp),
        mdp.action_mask,
        mdp.terminal,
        gamma,
        v,
        out,
        act,
    )
    return out, act


def policy_matvec(mdp: Any, actions: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(P_pi x)(s) = sum_s' p(s' | s, pi(s)) x(s') for a deterministic policy (0 on terminals)."""
    out = np.empty(mdp.n_states)
    _policy_matvec(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        mdp.n_actions,
        actions,
        mdp.terminal,
        np.ascontiguousarray(x, dtype=np.float64),
        out,
    )
    return out


def _reward(mdp: Any) -> np.ndarray:
    return np.ascontiguousarray(mdp.expected_reward)
