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
    "progressing_actions",
    "q_values",
    "termination_distances",
]


#: Reassociation for the sums, but no "no-inf/no-nan" assumptions (-inf marks A(s)).
_FAST = {"reassoc", "contract", "arcp", "nsz"}


@njit(cache=True, nogil=True)
def _gs_optimality(
    indptr: Any,
    nxt: Any,
    probs: Any,
    R: Any,
    mask: Any,
    terminal: Any,
    gamma: float,
    v: Any,
    order: Any,
) -> float:  # pragma: no cover - compiled
    # R and mask are the flat (S * A,) views; states are visited in ``order``. The
    # self-loop of each (s, a) is solved exactly: q = (r + gamma sum_{s' != s} p v(s'))
    # / (1 - gamma p(s | s, a)), the fixed point of that action's own backup at s.
    S = terminal.shape[0]
    A = R.shape[0] // S
    qs = np.empty(A)
    delta = 0.0
    for i in range(order.shape[0]):
        s = order[i]
        if terminal[s]:
            continue
        for a in range(A):
            row = s * A + a
            acc = 0.0
            stay = 0.0
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                j = nxt[k]
                if j == s:
                    stay += probs[k]
                else:
                    acc += probs[k] * v[np.uint64(j)]
            den = 1.0 - gamma * stay
            if den > 1e-12:
                q = (R[row] + gamma * acc) / den
            else:  # a pure self-loop at gamma = 1: the plain backup
                q = R[row] + gamma * (acc + stay * v[s])
            qs[a] = q if mask[row] else -np.inf
        best = qs[0]
        for a in range(1, A):
            best = max(best, qs[a])
        delta = max(delta, abs(best - v[s]))
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


def gauss_seidel_optimality_sweep(
    mdp: Any, gamma: float, v: np.ndarray, order: np.ndarray | None = None
) -> float:
    """One in-place sweep v(s) <- max_a q(s, a) over the states in ``order`` (default 0..S-1).

    q(s, a) = [r(s, a) + gamma sum_{s' != s} p(s'|s, a) v(s')] / (1 - gamma p(s|s, a)):
    the backup with its self-loop solved exactly (where 1 - gamma p(s|s, a) > 0), whose
    fixed point is v_* as well: with v = v_* it equals q_*(s, a) for an optimal a and
    is at most v_*(s) for the others. Later states already see the new values of
    earlier ones. The sweep is a gamma-contraction in the sup norm, whatever the order.
    Returns max_s |change|.
    """
    if order is None:
        order = np.arange(mdp.n_states, dtype=np.int64)
    return float(
        _gs_optimality(
            mdp.indptr,
            mdp.next_states,
            mdp.probs,
            _reward(mdp).reshape(-1),
            mdp.action_mask.reshape(-1),
            mdp.terminal,
            gamma,
            v,
            np.ascontiguousarray(order, dtype=np.int64),
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


@njit(cache=True, nogil=True)
def _q_values(
    indptr: Any, nxt: Any, probs: Any, R: Any, mask: Any, gamma: float, v: Any, q: Any
) -> None:  # pragma: no cover - compiled
    # One flat pass over the rows s * A + a, exactly like a CSR matrix-vector product:
    # no branch on A(s) (a select instead), so the loads of successive rows overlap.
    # ``R``, ``mask`` and ``q`` are the flat (S * A,) views. Without fastmath: the
    # reassociated (vectorised) 10-term sums are slower than the plain ones here.
    for row in range(q.shape[0]):
        acc = 0.0
        for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
            acc += probs[k] * v[np.uint64(nxt[k])]
        q[row] = R[row] + gamma * acc if mask[row] else -np.inf


@njit(cache=True, nogil=True)
def _row_max(
    q: Any, n_actions: int, terminal: Any, out: Any, act: Any
) -> None:  # pragma: no cover - compiled
    # max_a and argmax_a (the first one) of each row of the flat q; 0 and -1 on terminals.
    i = 0
    for s in range(terminal.shape[0]):
        best = -np.inf
        best_a = -1
        for a in range(n_actions):
            if q[i] > best:
                best = q[i]
                best_a = a
            i += 1
        if terminal[s]:
            best = 0.0
            best_a = -1
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


def q_values(mdp: Any, gamma: float, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """q(s, a) = r(s, a) + gamma sum_s' p(s'|s, a) v(s'), -inf where a is not in A(s).

    Args:
        mdp: The FiniteMDP.
        gamma: Discount rate.
        v: State values (S,).
        out: Optional (S, A) C-contiguous float64 array to write q into (reused across
            sweeps by the solvers); a new one by default.
    """
    q = np.empty((mdp.n_states, mdp.n_actions)) if out is None else out
    if not q.flags.c_contiguous or q.shape != (mdp.n_states, mdp.n_actions):
        raise ValueError("out must be a C-contiguous (S, A) float64 array")
    _q_values(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        _reward(mdp).reshape(-1),
        mdp.action_mask.reshape(-1),
        gamma,
        np.ascontiguousarray(v, dtype=np.float64),
        q.reshape(-1),
    )
    return q


def optimality_sweep(
    mdp: Any, gamma: float, v: np.ndarray, work: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """One synchronous Bellman optimality sweep: (T v)(s) = max_a q(s, a) and its argmax.

    Two compiled passes: :func:`q_values` over the outcome table (read once, like a bare
    sparse matrix-vector product), then a max over each state's row of q. Splitting
    them keeps the unpredictable max branch out of the memory-bound loop, which is
    what makes the sweep run at the speed of a bare ``P @ v``.

    Args:
        mdp: The FiniteMDP.
        gamma: Discount rate.
        v: State values (S,).
        work: Optional (S, A) float64 scratch array for q, reused across sweeps.

    Returns:
        ``(T v, greedy action indices)`` (0 and -1 on terminal states).
    """
    q = q_values(mdp, gamma, v, work)
    out = np.empty(mdp.n_states)
    act = np.empty(mdp.n_states, dtype=np.int64)
    _row_max(q.reshape(-1), mdp.n_actions, mdp.terminal, out, act)
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


@njit(cache=True, nogil=True)
def _termination_distances(
    indptr: Any, nxt: Any, probs: Any, allowed: Any, terminal: Any
) -> Any:  # pragma: no cover - compiled
    # Breadth-first search backwards from the terminal states over the edges s -> s'
    # with p(s' | s, a) > 0 for an allowed (s, a) (``allowed`` is the flat (S * A,) mask).
    # The reversed graph is built in CSR form first (counting sort by s').
    S = terminal.shape[0]
    A = allowed.shape[0] // S
    start = np.zeros(S + 1, dtype=np.int64)
    for row in range(S * A):
        if allowed[row]:
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                if probs[k] > 0.0:
                    start[np.uint64(nxt[k]) + 1] += 1
    for s in range(S):
        start[s + 1] += start[s]
    src = np.empty(start[S], dtype=nxt.dtype)
    fill = start[:S].copy()
    for row in range(S * A):
        if allowed[row]:
            s_from = row // A
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                if probs[k] > 0.0:
                    j = np.uint64(nxt[k])
                    src[fill[j]] = s_from
                    fill[j] += 1
    dist = np.full(S, -1, dtype=np.int64)
    queue = np.empty(S, dtype=np.int64)
    tail = 0
    for s in range(S):
        if terminal[s]:
            dist[s] = 0
            queue[tail] = s
            tail += 1
    head = 0
    while head < tail:
        u = queue[head]
        head += 1
        for e in range(start[u], start[u + 1]):
            w = np.int64(src[e])
            if dist[w] < 0 and not terminal[w]:
                dist[w] = dist[u] + 1
                queue[tail] = w
                tail += 1
    return dist


@njit(cache=True, nogil=True)
def _progressing_rows(
    indptr: Any, nxt: Any, probs: Any, allowed: Any, dist: Any, out: Any
) -> None:  # pragma: no cover - compiled
    # out[s * A + a]: (s, a) is allowed and can move (p > 0) to a state with a smaller
    # finite distance than s's own.
    S = dist.shape[0]
    A = allowed.shape[0] // S
    for row in range(S * A):
        s = row // A
        ok = False
        if allowed[row] and dist[s] > 0:
            for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
                d = dist[np.uint64(nxt[k])]
                if probs[k] > 0.0 and 0 <= d < dist[s]:
                    ok = True
                    break
        out[row] = ok


def termination_distances(mdp: Any, allowed: np.ndarray) -> np.ndarray:
    """d(s): the fewest steps from s to a terminal state using only ``allowed`` actions.

    d(s) = 0 on terminal states, d(s) = 1 + min {d(s') : p(s' | s, a) > 0, a allowed in s}
    elsewhere, and -1 where no terminal state can be reached that way. One breadth-first
    search backwards from the terminal states, linear in the number of outcomes.

    Args:
        mdp: The FiniteMDP.
        allowed: Boolean (S, A) mask of the actions that may be used.
    """
    return np.asarray(
        _termination_distances(
            mdp.indptr,
            mdp.next_states,
            mdp.probs,
            np.ascontiguousarray(allowed, dtype=np.bool_).reshape(-1),
            mdp.terminal,
        )
    )


def progressing_actions(mdp: Any, allowed: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The allowed (s, a) that can move to a state with a smaller finite ``dist`` (S, A)."""
    flat = np.ascontiguousarray(allowed, dtype=np.bool_).reshape(-1)
    out = np.empty(flat.shape[0], dtype=np.bool_)
    _progressing_rows(mdp.indptr, mdp.next_states, mdp.probs, flat, dist, out)
    return out.reshape(mdp.n_states, mdp.n_actions)
