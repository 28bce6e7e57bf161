"""Compiled sweeps over the MDP's outcome table (numba).

Each kernel reads the outcomes of p(s' | s, a) straight from ``mdp.indptr``,
``mdp.next_states`` and ``mdp.probs`` in one pass, like a bare sparse matrix-vector
product, without building the (S * A, S) matrix or any (S, A) temporary. Indices are
read as unsigned integers so that no negative-index wraparound check is compiled in.
"""

from __future__ import annotations

import math
import os
import weakref
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit, prange

__all__ = [
    "BLOCK_MIN_OUTCOMES",
    "PARALLEL_MIN_OUTCOMES",
    "SWEEP_BLOCKS",
    "SharedRows",
    "SweepBlocks",
    "component_policy_solve",
    "component_solver_name",
    "dense_block_max",
    "dense_policy_system",
    "first_greedy_probs",
    "gauss_seidel_expectation_sweep",
    "gauss_seidel_optimality_sweep",
    "improved_actions",
    "num_threads",
    "optimality_sweep",
    "optimality_values",
    "policy_matvec",
    "progressing_actions",
    "q_values",
    "shared_rows",
    "small_components",
    "solve_by_components",
    "sweep_blocks",
    "termination_distances",
]


_STARTED = False


def num_threads() -> int:
    """The number of numba's threads (``numba.set_num_threads``), asked before threaded passes.

    The first call starts numba's threads. Where numba runs them on GNU OpenMP (its
    default threading layer when TBB is not installed) and ``OMP_WAIT_POLICY`` is not
    set, they are started with ``OMP_WAIT_POLICY=PASSIVE`` (read by numba's OpenMP
    library as it loads; the variable is removed again at once): by default an OpenMP
    thread spins after each threaded pass, and where the other cores are busy the
    spinning thread takes time from the thread running the sequential code between
    passes. Measured on 2 cores with the second one busy, a 200 x 200 gridworld solved
    on 2 threads ran 0.79x as fast as on 1 with spinning threads, 0.99x with passive
    ones; with the second core idle, 1.30x and 1.26x as fast.
    """
    global _STARTED
    if not _STARTED:
        _STARTED = True
        if "OMP_WAIT_POLICY" not in os.environ:
            os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
            try:
                numba.get_num_threads()  # loads numba's threading layer, which reads it
            finally:
                del os.environ["OMP_WAIT_POLICY"]
    return int(numba.get_num_threads())


#: Reassociation for the sums, but no "no-inf/no-nan" assumptions (-inf marks A(s)).
_FAST = {"reassoc", "contract", "arcp", "nsz"}


@njit(cache=True, nogil=True, inline="always")
def _split_row(
    indptr: Any, nxt: Any, probs: Any, row: Any, s: Any, v: Any
) -> Any:  # pragma: no cover
    # (sum_{s' != s} p(s' | row) v(s'), p(s | row)): a row's backup without its self-loop.
    acc = 0.0
    stay = 0.0
    for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
        j = nxt[k]
        if j == s:
            stay += probs[k]
        else:
            acc += probs[k] * v[np.uint64(j)]
    return acc, stay


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
    lo: int,
    hi: int,
) -> float:  # pragma: no cover - compiled
    # R and mask are the flat (S * A,) views; the states order[lo:hi] are visited in
    # turn. The self-loop of each (s, a) is solved exactly: q = (r + gamma sum_{s' != s}
    # p v(s')) / (1 - gamma p(s | s, a)), the fixed point of that action's own backup at
    # s. ``v`` may be longer than S (see ``_gs_blocks``): ``nxt`` then points some
    # outcomes at a snapshot v[S + s'] instead of v[s'].
    S = terminal.shape[0]
    A = R.shape[0] // S
    qs = np.empty(A)
    delta = 0.0
    for i in range(lo, hi):
        s = order[i]
        if terminal[s]:
            continue
        for a in range(A):
            row = s * A + a
            acc, stay = _split_row(indptr, nxt, probs, row, s, v)
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


# Block sweeps: block b visits order[bounds[b]:bounds[b + 1]] in place; every outcome
# into another block reads the snapshot v[S:] (its ``nxt`` is shifted by S), so no
# block reads a value another block writes. The blocks run one after the other or on
# numba's threads, with the same numbers either way.


@njit(cache=True, nogil=True)
def _gs_blocks(
    indptr: Any,
    nxt: Any,
    probs: Any,
    R: Any,
    mask: Any,
    terminal: Any,
    gamma: float,
    v: Any,
    order: Any,
    bounds: Any,
    deltas: Any,
) -> None:  # pragma: no cover - compiled
    for b in range(deltas.shape[0]):
        deltas[b] = _gs_optimality(
            indptr, nxt, probs, R, mask, terminal, gamma, v, order, bounds[b], bounds[b + 1]
        )


@njit(cache=True, nogil=True, parallel=True)
def _gs_blocks_par(
    indptr: Any,
    nxt: Any,
    probs: Any,
    R: Any,
    mask: Any,
    terminal: Any,
    gamma: float,
    v: Any,
    order: Any,
    bounds: Any,
    deltas: Any,
) -> None:  # pragma: no cover - compiled
    for b in prange(deltas.shape[0]):
        deltas[b] = _gs_optimality(
            indptr, nxt, probs, R, mask, terminal, gamma, v, order, bounds[b], bounds[b + 1]
        )


@njit(cache=True, nogil=True)
def _level_blocks(order: Any, level: Any, n_blocks: int) -> Any:  # pragma: no cover - compiled
    # Each run of equal ``level`` along ``order`` is cut into n_blocks equal parts in
    # its order, part b going to block b; returns the order block by block (each block
    # keeping the sweep order), the block bounds and each state's block.
    S = order.shape[0]
    block = np.empty(S, dtype=np.int64)
    count = np.zeros(n_blocks + 1, dtype=np.int64)
    i = 0
    while i < S:
        j = i
        while j < S and level[order[j]] == level[order[i]]:
            j += 1
        for k in range(i, j):
            b = (k - i) * n_blocks // (j - i)
            block[order[k]] = b
            count[b + 1] += 1
        i = j
    for b in range(n_blocks):
        count[b + 1] += count[b]
    bounds = count.copy()
    fill = count[:n_blocks].copy()
    out = np.empty(S, dtype=np.int64)
    for k in range(S):
        x = order[k]
        out[fill[block[x]]] = x
        fill[block[x]] += 1
    return out, bounds, block


@njit(cache=True, nogil=True, inline="always")
def _shift_state(
    indptr: Any, nxt: Any, n_actions: int, block: Any, u: Any, shifted: Any
) -> None:  # pragma: no cover - compiled
    # The outcomes of state u's rows, moved by S where they lead into another block.
    S = block.shape[0]
    for k in range(np.int64(indptr[u * n_actions]), np.int64(indptr[(u + 1) * n_actions])):
        t = np.int64(nxt[k])
        shifted[k] = t if block[t] == block[u] else t + S


@njit(cache=True, nogil=True)
def _shift_outcomes(
    indptr: Any, nxt: Any, n_actions: int, block: Any, shifted: Any
) -> None:  # pragma: no cover - compiled
    for u in range(block.shape[0]):
        _shift_state(indptr, nxt, n_actions, block, u, shifted)


@njit(cache=True, nogil=True, parallel=True)
def _shift_outcomes_par(
    indptr: Any, nxt: Any, n_actions: int, block: Any, shifted: Any
) -> None:  # pragma: no cover - compiled
    for u in prange(block.shape[0]):
        _shift_state(indptr, nxt, n_actions, block, u, shifted)


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


#: In-place sweeps over models with at least this many outcomes are split into
#: ``SWEEP_BLOCKS`` blocks (see :func:`sweep_blocks`), whatever the number of threads,
#: so that 1 and 2 threads give the same numbers; below it one block (the plain
#: Gauss-Seidel sweep) is cheaper than the threads' start-up.
BLOCK_MIN_OUTCOMES = 100_000

#: The number of blocks of a split in-place sweep (see :data:`BLOCK_MIN_OUTCOMES`).
SWEEP_BLOCKS = 2


class SweepBlocks(NamedTuple):
    """A split of an in-place sweep into blocks (see :func:`sweep_blocks`)."""

    order: np.ndarray
    bounds: np.ndarray
    next_states: np.ndarray
    work: np.ndarray


def sweep_blocks(
    mdp: Any, order: np.ndarray, level: np.ndarray, n_blocks: int = SWEEP_BLOCKS
) -> SweepBlocks:
    """Split an in-place sweep in ``order`` into ``n_blocks`` blocks of states.

    Each run of states of equal ``level`` along ``order`` (the states at one distance
    from the terminal states, in a terminal-first order) is cut into ``n_blocks`` equal
    parts, part b going to block b, so that every block holds states at every distance
    and values flow to the terminal states inside each block. A block sweep (see
    :func:`gauss_seidel_optimality_sweep`) updates each block's states in place in the
    sweep order and reads the other blocks' states as they were when the sweep began:
    Gauss-Seidel inside a block, Jacobi between blocks.
    """
    o = np.ascontiguousarray(order, dtype=np.int64)
    lv = np.ascontiguousarray(level, dtype=np.int64)
    nxt = mdp.next_states
    # indices up to 2 S - 1, in the table's own integer type where they fit
    wide = 2 * mdp.n_states - 1 > np.iinfo(nxt.dtype).max
    shifted = np.empty(nxt.shape[0], dtype=np.int64 if wide else nxt.dtype)
    out, bounds, block = _level_blocks(o, lv, n_blocks)
    par = mdp.n_outcomes >= BLOCK_MIN_OUTCOMES and num_threads() > 1
    (_shift_outcomes_par if par else _shift_outcomes)(
        mdp.indptr, nxt, mdp.n_actions, block, shifted
    )
    return SweepBlocks(out, bounds, shifted, np.empty(2 * mdp.n_states))


def gauss_seidel_optimality_sweep(
    mdp: Any,
    gamma: float,
    v: np.ndarray,
    order: np.ndarray | None = None,
    blocks: SweepBlocks | None = None,
) -> float:
    """One in-place sweep v(s) <- max_a q(s, a) over the states in ``order`` (default 0..S-1).

    q(s, a) = [r(s, a) + gamma sum_{s' != s} p(s'|s, a) v(s')] / (1 - gamma p(s|s, a)):
    the backup with its self-loop solved exactly (where 1 - gamma p(s|s, a) > 0), whose
    fixed point is v_* as well: with v = v_* it equals q_*(s, a) for an optimal a and
    is at most v_*(s) for the others. Later states already see the new values of
    earlier ones. Returns max_s |change|.

    With ``blocks`` (from :func:`sweep_blocks`; ``order`` is then ignored) each block
    is swept in its own order, in place, while the states of other blocks are read as
    they were when the sweep began; the blocks run on numba's threads when there are
    several, with the same result bit for bit (no block reads what another writes).

    Either way the sweep G is a gamma-contraction in the sup norm with fixed point
    v_*, which is what the stopping rule of :func:`value_iteration` needs. Proof: let
    u, w be two value vectors and e = max_s |u(s) - w(s)|. The states are updated one
    at a time within a block; by induction along that order, every value a backup
    reads differs between the runs from u and from w by at most e (a value from the
    start of the sweep, or from another block's snapshot) or by at most gamma e <= e
    (one already updated). A backup's map from the values it reads is monotone with
    total weight gamma (1 - p(s|s, a)) / (1 - gamma p(s|s, a)) <= gamma on the other
    states, and max over a keeps that bound, so |(G u)(s) - (G w)(s)| <= gamma e for
    every s. Then from v_{k+1} = G v_k and v_* = G v_*, ||v_{k+1} - v_*|| <= gamma
    ||v_k - v_*|| <= gamma (||v_k - v_{k+1}|| + ||v_{k+1} - v_*||), so ||v_{k+1} - v_*||
    <= gamma / (1 - gamma) max_s |v_{k+1}(s) - v_k(s)|.
    """
    R = _reward(mdp).reshape(-1)
    mask = mdp.action_mask.reshape(-1)
    if blocks is None:
        if order is None:
            order = np.arange(mdp.n_states, dtype=np.int64)
        o = np.ascontiguousarray(order, dtype=np.int64)
        return float(
            _gs_optimality(
                mdp.indptr,
                mdp.next_states,
                mdp.probs,
                R,
                mask,
                mdp.terminal,
                gamma,
                v,
                o,
                0,
                o.shape[0],
            )
        )
    S = mdp.n_states
    w = blocks.work
    w[:S] = v
    w[S:] = v
    deltas = np.zeros(blocks.bounds.shape[0] - 1)
    kernel = _gs_blocks_par if num_threads() > 1 else _gs_blocks
    kernel(
        mdp.indptr,
        blocks.next_states,
        mdp.probs,
        R,
        mask,
        mdp.terminal,
        gamma,
        w,
        blocks.order,
        blocks.bounds,
        deltas,
    )
    v[:] = w[:S]
    return float(deltas.max(initial=0.0))


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


#: Synchronous sweeps run on all of numba's threads (``numba.set_num_threads``) when the
#: model has at least this many outcomes; below it the thread start-up costs more than
#: it saves. Every state's (or row's) value is computed by one thread, in the same order
#: of terms as the sequential kernel, so the results are identical bit for bit.
PARALLEL_MIN_OUTCOMES = 2_000_000


@njit(cache=True, nogil=True)
def _row_dot(indptr: Any, nxt: Any, probs: Any, row: Any, v: Any) -> float:  # pragma: no cover
    # sum_k probs[k] v[nxt[k]] over one row of the outcome table, in storage order (a
    # ``while`` over an unsigned index: a tighter loop than ``range`` over one).
    acc = 0.0
    k = np.uint64(indptr[row])
    end = np.uint64(indptr[row + 1])
    while k < end:
        acc += probs[k] * v[np.uint64(nxt[k])]
        k += np.uint64(1)
    return acc


# Each kernel below comes twice, the same loop body over ``range`` (sequential) and over
# ``prange`` (split over threads); only the loop differs.
#
# q-values: one flat pass over the rows s * A + a, exactly like a CSR matrix-vector
# product: no branch on A(s) (a select instead), so the loads of successive rows
# overlap. ``R``, ``mask`` and ``q`` are the flat (S * A,) views. Without fastmath: the
# reassociated (vectorised) 10-term sums are slower than the plain ones here.


@njit(cache=True, nogil=True)
def _q_values(
    indptr: Any, nxt: Any, probs: Any, R: Any, mask: Any, gamma: float, v: Any, q: Any
) -> None:  # pragma: no cover - compiled
    for row in range(q.shape[0]):
        acc = _row_dot(indptr, nxt, probs, row, v)
        q[row] = R[row] + gamma * acc if mask[row] else -np.inf


@njit(cache=True, nogil=True, parallel=True)
def _q_values_par(
    indptr: Any, nxt: Any, probs: Any, R: Any, mask: Any, gamma: float, v: Any, q: Any
) -> None:  # pragma: no cover - compiled
    for row in prange(q.shape[0]):
        acc = _row_dot(indptr, nxt, probs, row, v)
        q[row] = R[row] + gamma * acc if mask[row] else -np.inf


# Shared rows: w[u] = sum_s' p(s' | u) v(s') once per distinct row u, then
# q[row] = R[row] + gamma w[row_of[row]].


@njit(cache=True, nogil=True)
def _row_dots(indptr: Any, nxt: Any, probs: Any, v: Any, w: Any) -> None:  # pragma: no cover
    for u in range(w.shape[0]):
        w[u] = _row_dot(indptr, nxt, probs, u, v)


@njit(cache=True, nogil=True, parallel=True)
def _row_dots_par(indptr: Any, nxt: Any, probs: Any, v: Any, w: Any) -> None:  # pragma: no cover
    for u in prange(w.shape[0]):
        w[u] = _row_dot(indptr, nxt, probs, u, v)


@njit(cache=True, nogil=True)
def _q_from_rows(
    row_of: Any, w: Any, R: Any, mask: Any, gamma: float, q: Any
) -> None:  # pragma: no cover - compiled
    for row in range(q.shape[0]):
        q[row] = R[row] + gamma * w[row_of[row]] if mask[row] else -np.inf


@njit(cache=True, nogil=True)
def _max_of_row(q: Any, n_actions: int, s: Any) -> Any:  # pragma: no cover - compiled
    # max_a and the first argmax_a of row s of the flat q.
    best = -np.inf
    best_a = -1
    i = s * n_actions
    for a in range(n_actions):
        if q[i + a] > best:
            best = q[i + a]
            best_a = a
    return best, best_a


@njit(cache=True, nogil=True)
def _row_max(
    q: Any, n_actions: int, terminal: Any, out: Any, act: Any
) -> None:  # pragma: no cover - compiled
    # max_a and argmax_a (the first one) of each row of the flat q; 0 and -1 on terminals.
    for s in range(terminal.shape[0]):
        best, best_a = _max_of_row(q, n_actions, s)
        out[s] = 0.0 if terminal[s] else best
        act[s] = -1 if terminal[s] else best_a


@njit(cache=True, nogil=True, parallel=True)
def _row_max_par(
    q: Any, n_actions: int, terminal: Any, out: Any, act: Any
) -> None:  # pragma: no cover - compiled
    for s in prange(terminal.shape[0]):
        best, best_a = _max_of_row(q, n_actions, s)
        out[s] = 0.0 if terminal[s] else best
        act[s] = -1 if terminal[s] else best_a


@njit(cache=True, nogil=True)
def _policy_matvec(
    indptr: Any, nxt: Any, probs: Any, n_actions: int, act: Any, terminal: Any, x: Any, out: Any
) -> None:  # pragma: no cover - compiled
    for s in range(terminal.shape[0]):
        out[s] = 0.0 if terminal[s] else _row_dot(indptr, nxt, probs, s * n_actions + act[s], x)


@njit(cache=True, nogil=True, parallel=True)
def _policy_matvec_par(
    indptr: Any, nxt: Any, probs: Any, n_actions: int, act: Any, terminal: Any, x: Any, out: Any
) -> None:  # pragma: no cover - compiled
    for s in prange(terminal.shape[0]):
        out[s] = 0.0 if terminal[s] else _row_dot(indptr, nxt, probs, s * n_actions + act[s], x)


# T v without its argmax (value iteration's synchronous sweep): one pass over the rows,
# the maximum taken as each row's sum is done (``max`` compiles to a branch-free
# select, so successive rows' loads still overlap); ``Rm`` is the flat r(s, a) with
# -inf on unavailable actions, so no mask is read either. Written out in the loop
# (not through ``_row_dot``): each row's end is the next row's start, read once, and
# a ``while`` over an unsigned index compiles to a tighter loop than ``range`` over
# one; the sum is the same, term by term, so the values are identical bit for bit.
# On the 200 x 200 grid this took the sweep from 1.6x to 1.2x a bare CSR product.


@njit(cache=True, nogil=True, inline="always")
def _optimality_value(
    indptr: Any, nxt: Any, probs: Any, Rm: Any, terminal: Any, gamma: float, v: Any, s: Any
) -> float:  # pragma: no cover - compiled
    # (T v)(s) = max_a Rm[s, a] + gamma sum_s' p(s' | s, a) v(s'); 0 at a terminal s.
    A = Rm.shape[0] // terminal.shape[0]
    best = -np.inf
    hi = np.uint64(indptr[s * A])
    for a in range(A):
        row = s * A + a
        k = hi
        hi = np.uint64(indptr[row + 1])
        acc = 0.0
        while k < hi:
            acc += probs[k] * v[np.uint64(nxt[k])]
            k += np.uint64(1)
        best = max(best, Rm[row] + gamma * acc)
    return 0.0 if terminal[s] else best


@njit(cache=True, nogil=True)
def _optimality_values(
    indptr: Any, nxt: Any, probs: Any, Rm: Any, terminal: Any, gamma: float, v: Any, out: Any
) -> None:  # pragma: no cover - compiled
    for s in range(terminal.shape[0]):
        out[s] = _optimality_value(indptr, nxt, probs, Rm, terminal, gamma, v, s)


@njit(cache=True, nogil=True, parallel=True)
def _optimality_values_par(
    indptr: Any, nxt: Any, probs: Any, Rm: Any, terminal: Any, gamma: float, v: Any, out: Any
) -> None:  # pragma: no cover - compiled
    for s in prange(terminal.shape[0]):
        out[s] = _optimality_value(indptr, nxt, probs, Rm, terminal, gamma, v, s)


def _parallel(n_reads: int) -> bool:
    """Whether a pass reading this many outcomes (or q entries) goes to the threaded kernels."""
    return n_reads >= PARALLEL_MIN_OUTCOMES and num_threads() > 1


def q_values(mdp: Any, gamma: float, v: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """q(s, a) = r(s, a) + gamma sum_s' p(s'|s, a) v(s'), -inf where a is not in A(s).

    Args:
        mdp: The FiniteMDP.
        gamma: Discount rate.
        v: State values (S,).
        out: Optional (S, A) C-contiguous float64 array to write q into (reused across
            sweeps by the solvers); a new one by default.

    Where many (s, a) share one distribution p(. | s, a) (see :func:`shared_rows`),
    each distinct sum over s' is computed once; on large models the rows are split
    over numba's threads. Either way each q(s, a) is the same sum, in the same order,
    so the result is identical bit for bit.
    """
    q = np.empty((mdp.n_states, mdp.n_actions)) if out is None else out
    if not q.flags.c_contiguous or q.shape != (mdp.n_states, mdp.n_actions):
        raise ValueError("out must be a C-contiguous (S, A) float64 array")
    vv = np.ascontiguousarray(v, dtype=np.float64)
    R, mask, flat = _reward(mdp).reshape(-1), mdp.action_mask.reshape(-1), q.reshape(-1)
    shared = shared_rows(mdp)
    if shared is not None:
        w = np.empty(shared.indptr.shape[0] - 1)
        dots = _row_dots_par if _parallel(shared.probs.shape[0]) else _row_dots
        dots(shared.indptr, shared.next_states, shared.probs, vv, w)
        _q_from_rows(shared.row_of, w, R, mask, gamma, flat)
    else:
        kernel = _q_values_par if _parallel(mdp.n_outcomes) else _q_values
        kernel(mdp.indptr, mdp.next_states, mdp.probs, R, mask, gamma, vv, flat)
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
    row_max = _row_max_par if _parallel(q.size) else _row_max
    row_max(q.reshape(-1), mdp.n_actions, mdp.terminal, out, act)
    return out, act


@njit(cache=True, nogil=True, inline="always")
def _first_greedy_row(
    q: Any, mask: Any, tol: float, s: Any, probs: Any
) -> None:  # pragma: no cover - compiled
    # probs[s, a] = 1 for the first a in A(s) with q(s, a) >= best - tol * max(1, |best|),
    # written with selects (no branch on the values: ties and near-ties are common).
    A = q.shape[1]
    best = -np.inf
    for a in range(A):
        best = max(best, q[s, a] if mask[s, a] else -np.inf)
    low = best - tol * max(1.0, abs(best))
    first = A
    for a in range(A - 1, -1, -1):
        x = q[s, a] if mask[s, a] else -np.inf
        first = a if x >= low else first
    if first < A and best > -np.inf:
        probs[s, first] = 1.0


@njit(cache=True, nogil=True)
def _first_greedy(
    q: Any, mask: Any, terminal: Any, tol: float, probs: Any
) -> None:  # pragma: no cover - compiled
    for s in range(terminal.shape[0]):
        if not terminal[s]:
            _first_greedy_row(q, mask, tol, s, probs)


@njit(cache=True, nogil=True, parallel=True)
def _first_greedy_par(
    q: Any, mask: Any, terminal: Any, tol: float, probs: Any
) -> None:  # pragma: no cover - compiled
    for s in prange(terminal.shape[0]):
        if not terminal[s]:
            _first_greedy_row(q, mask, tol, s, probs)


def first_greedy_probs(mdp: Any, q: np.ndarray, tol: float) -> np.ndarray:
    """The (S, A) one-hot rows of the first greedy action (zero rows on terminal states).

    The first greedy action of s is the first a in A(s) with
    q(s, a) >= max_{b in A(s)} q(s, b) - tol * max(1, |max_{b in A(s)} q(s, b)|).
    One compiled pass over q, on numba's threads from
    ``BLOCK_MIN_OUTCOMES`` entries of q (each row is one thread's, so the rows are the
    same either way).
    """
    probs = np.zeros((mdp.n_states, mdp.n_actions))
    qq = np.ascontiguousarray(q, dtype=np.float64)
    par = qq.size >= BLOCK_MIN_OUTCOMES and num_threads() > 1
    (_first_greedy_par if par else _first_greedy)(qq, mdp.action_mask, mdp.terminal, tol, probs)
    return probs


@njit(cache=True, nogil=True, inline="always")
def _improve_row(
    q: Any, current: Any, tie_tol: float, s: Any, new: Any
) -> bool:  # pragma: no cover
    # new[s]: the first argmax of q(s, .) unless current[s] is within the tie tolerance
    # of it; whether it changed.
    A = q.shape[1]
    best = q[s, 0]
    best_a = 0
    for a in range(1, A):
        better = q[s, a] > best
        best_a = a if better else best_a
        best = q[s, a] if better else best
    keep = q[s, current[s]] >= best - tie_tol * max(1.0, abs(best))
    new[s] = current[s] if keep else best_a
    return not keep and best_a != current[s]


@njit(cache=True, nogil=True)
def _improve(
    q: Any, current: Any, terminal: Any, tie_tol: float, new: Any
) -> int:  # pragma: no cover - compiled
    changed = 0
    for s in range(terminal.shape[0]):
        if _improve_row(q, current, tie_tol, s, new) and not terminal[s]:
            changed += 1
    return changed


@njit(cache=True, nogil=True, parallel=True)
def _improve_par(
    q: Any, current: Any, terminal: Any, tie_tol: float, new: Any
) -> int:  # pragma: no cover - compiled
    changed = 0
    for s in prange(terminal.shape[0]):
        if _improve_row(q, current, tie_tol, s, new) and not terminal[s]:
            changed += 1
    return changed


def improved_actions(
    mdp: Any, q: np.ndarray, current: np.ndarray, tie_tol: float
) -> tuple[np.ndarray, int]:
    """Policy improvement: pi'(s) = argmax_a q(s, a), keeping pi(s) where it ties.

    pi'(s) = pi(s) if q(s, pi(s)) >= max_a q(s, a) - tie_tol * max(1, |max_a q(s, a)|),
    else the first maximising a. Returns pi' and the number of non-terminal states whose
    action changed. One compiled pass over q, on numba's threads from
    ``BLOCK_MIN_OUTCOMES`` entries (each row is one thread's: the same result).
    """
    new = np.empty(mdp.n_states, dtype=np.int64)
    qq = np.ascontiguousarray(q, dtype=np.float64)
    cur = np.ascontiguousarray(current, dtype=np.int64)
    par = qq.size >= BLOCK_MIN_OUTCOMES and num_threads() > 1
    changed = (_improve_par if par else _improve)(qq, cur, mdp.terminal, tie_tol, new)
    return new, int(changed)


_MASKED: weakref.WeakKeyDictionary[Any, np.ndarray] = weakref.WeakKeyDictionary()


def _masked_flat_reward(mdp: Any) -> np.ndarray:
    """r(s, a) with -inf where a is not in A(s), flat (S * A,); kept with the model."""
    found = _MASKED.get(mdp)
    if found is None:
        found = np.where(mdp.action_mask, _reward(mdp), -np.inf).reshape(-1)
        _MASKED[mdp] = found
    return found


def optimality_values(mdp: Any, gamma: float, v: np.ndarray) -> np.ndarray:
    """(T v)(s) = max_a q(s, a) (0 on terminal states), without the argmax.

    Value iteration's synchronous sweep. One compiled pass over the outcome table that
    takes each state's maximum as its rows are summed, with no (S, A) temporary, where
    :func:`optimality_sweep` writes q and then reads it back; on models whose rows
    repeat (see :func:`shared_rows`) it is :func:`optimality_sweep`'s value. Either way
    the numbers are the same, bit for bit.
    """
    if shared_rows(mdp) is not None:
        return optimality_sweep(mdp, gamma, v)[0]
    out = np.empty(mdp.n_states)
    kernel = _optimality_values_par if _parallel(mdp.n_outcomes) else _optimality_values
    kernel(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        _masked_flat_reward(mdp),
        mdp.terminal,
        gamma,
        np.ascontiguousarray(v, dtype=np.float64),
        out,
    )
    return out


def policy_matvec(mdp: Any, actions: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(P_pi x)(s) = sum_s' p(s' | s, pi(s)) x(s') for a deterministic policy (0 on terminals)."""
    out = np.empty(mdp.n_states)
    kernel = (
        _policy_matvec_par if _parallel(mdp.n_outcomes // max(mdp.n_actions, 1)) else _policy_matvec
    )
    kernel(
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


# The edges s -> s' with p(s' | s, a) > 0 over the allowed rows (flat (S * A,) mask),
# reversed into CSR form by a counting sort on s': the sources of the edges into s'
# are src[start[s']:start[s' + 1]], in increasing order. The states are cut into
# ``counts.shape[0]`` consecutive chunks, each counted and filled on its own (in turn,
# or on numba's threads): chunk c's edges into s' go after those of chunks before it,
# so the result is the same for any number of chunks.


@njit(cache=True, nogil=True, inline="always")
def _chunk_edges(
    indptr: Any, nxt: Any, probs: Any, allowed: Any, S: int, c: int, counts: Any, src: Any
) -> None:  # pragma: no cover - compiled
    # Count chunk c's edges into counts[c] (``src`` empty), or place them at counts[c].
    A = allowed.shape[0] // S
    C = counts.shape[0]
    fill = src.shape[0] > 0
    for s in range(c * S // C, (c + 1) * S // C):
        for row in range(s * A, (s + 1) * A):
            if allowed[row]:
                for k in range(np.int64(indptr[row]), np.int64(indptr[row + 1])):
                    if probs[k] > 0.0:
                        j = np.int64(nxt[k])
                        if fill:
                            src[counts[c, j]] = s
                        counts[c, j] += 1


@njit(cache=True, nogil=True)
def _edge_offsets(counts: Any) -> Any:  # pragma: no cover - compiled
    # start[j] from the chunks' counts, and each chunk's first slot for target j.
    C, S = counts.shape
    start = np.zeros(S + 1, dtype=np.int64)
    for j in range(S):
        at = start[j]
        for c in range(C):
            n = counts[c, j]
            counts[c, j] = at
            at += n
        start[j + 1] = at
    return start


@njit(cache=True, nogil=True)
def _reversed_graph(
    indptr: Any, nxt: Any, probs: Any, allowed: Any, S: int, n_chunks: int
) -> Any:  # pragma: no cover - compiled
    counts = np.zeros((n_chunks, S), dtype=np.int64)
    none = np.empty(0, dtype=np.int64)
    for c in range(n_chunks):
        _chunk_edges(indptr, nxt, probs, allowed, S, c, counts, none)
    start = _edge_offsets(counts)
    src = np.empty(start[S], dtype=np.int64)
    for c in range(n_chunks):
        _chunk_edges(indptr, nxt, probs, allowed, S, c, counts, src)
    return start, src


@njit(cache=True, nogil=True, parallel=True)
def _reversed_graph_par(
    indptr: Any, nxt: Any, probs: Any, allowed: Any, S: int, n_chunks: int
) -> Any:  # pragma: no cover - compiled
    counts = np.zeros((n_chunks, S), dtype=np.int64)
    none = np.empty(0, dtype=np.int64)
    for c in prange(n_chunks):
        _chunk_edges(indptr, nxt, probs, allowed, S, c, counts, none)
    start = _edge_offsets(counts)
    src = np.empty(start[S], dtype=np.int64)
    for c in prange(n_chunks):
        _chunk_edges(indptr, nxt, probs, allowed, S, c, counts, src)
    return start, src


@njit(cache=True, nogil=True)
def _termination_distances(start: Any, src: Any, terminal: Any) -> Any:  # pragma: no cover
    # Breadth-first search backwards from the terminal states over the reversed edges.
    S = terminal.shape[0]
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


#: The last (allowed mask, distances) of each model: the solvers ask for the distances
#: under the full action mask several times in one solve (is the task episodic? the
#: sweep order; a proper first policy), and the model's arrays never change.
_DISTANCES: weakref.WeakKeyDictionary[Any, tuple[np.ndarray, np.ndarray]] = (
    weakref.WeakKeyDictionary()
)


def termination_distances(mdp: Any, allowed: np.ndarray) -> np.ndarray:
    """d(s): the fewest steps from s to a terminal state using only ``allowed`` actions.

    d(s) = 0 on terminal states, d(s) = 1 + min {d(s') : p(s' | s, a) > 0, a allowed in s}
    elsewhere, and -1 where no terminal state can be reached that way. One breadth-first
    search backwards from the terminal states, linear in the number of outcomes; the
    last mask asked of each model is remembered with its distances.

    Args:
        mdp: The FiniteMDP.
        allowed: Boolean (S, A) mask of the actions that may be used.

    Returns:
        A new (S,) int64 array (the caller may change it).
    """
    flat = np.ascontiguousarray(allowed, dtype=np.bool_).reshape(-1)
    found = _DISTANCES.get(mdp)
    if found is not None and np.array_equal(found[0], flat):
        return found[1].copy()
    par = mdp.n_outcomes >= BLOCK_MIN_OUTCOMES and num_threads() > 1
    reverse = _reversed_graph_par if par else _reversed_graph
    S = mdp.n_states
    start, src = reverse(
        mdp.indptr, mdp.next_states, mdp.probs, flat, S, num_threads() if par else 1
    )
    dist = np.asarray(_termination_distances(start, src, mdp.terminal))
    _DISTANCES[mdp] = (flat.copy(), dist.copy())
    return dist


def progressing_actions(mdp: Any, allowed: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """The allowed (s, a) that can move to a state with a smaller finite ``dist`` (S, A)."""
    flat = np.ascontiguousarray(allowed, dtype=np.bool_).reshape(-1)
    out = np.empty(flat.shape[0], dtype=np.bool_)
    _progressing_rows(mdp.indptr, mdp.next_states, mdp.probs, flat, dist, out)
    return out.reshape(mdp.n_states, mdp.n_actions)


# ---------------------------------------------------------------- shared outcome rows
#
# Many models repeat the same distribution p(. | s, a) in many rows: in an inventory
# the next stock depends on s + a only, in Jack's car rental on the cars at each
# location after the move (Sutton & Barto section 6.8 call these afterstates). A sum
# sum_s' p(s' | s, a) v(s') is then the same for every (s, a) sharing the row, and a
# sweep need compute it once per distinct row.

_FNV = np.uint64(0x100000001B3)


@njit(cache=True, nogil=True)
def _distinct_rows(
    indptr: Any, nxt: Any, pbits: Any, max_fraction: float
) -> Any:  # pragma: no cover - compiled
    # Open-addressing hash table over the rows (keys: next states and the probabilities'
    # bit patterns, compared exactly, entry by entry). Returns (number of distinct
    # rows, row -> distinct id, representative row of each id), or n = -1 as soon as
    # the distinct rows hold more than ``max_fraction`` of all outcomes, or (tables of
    # 10^6 outcomes or more) of those of the first quarter of the rows once it is read:
    # too little sharing to pay off.
    n_rows = indptr.shape[0] - 1
    size = 1
    while size < 2 * n_rows:
        size *= 2
    table = np.full(size, -1, dtype=np.int64)
    row_of = np.empty(n_rows, dtype=np.int64)
    reps = np.empty(n_rows, dtype=np.int64)
    n = 0
    kept = np.int64(0)
    max_outcomes = max_fraction * np.float64(indptr[n_rows])
    for row in range(n_rows):
        lo, hi = np.int64(indptr[row]), np.int64(indptr[row + 1])
        # the hash reads a few outcomes only (length, two first, two last); the exact
        # comparison below reads the rest
        h = np.uint64(0xCBF29CE484222325) ^ np.uint64(hi - lo)
        for k in (lo, lo + 1, hi - 2, hi - 1):
            if lo <= k < hi:
                h = (h ^ np.uint64(nxt[k])) * _FNV
                h = (h ^ pbits[k]) * _FNV
        slot = np.int64(h & np.uint64(size - 1))
        while True:
            u = table[slot]
            if u < 0:
                table[slot] = n
                reps[n] = row
                row_of[row] = n
                n += 1
                kept += hi - lo
                break
            r = reps[u]
            rlo = np.int64(indptr[r])
            same = np.int64(indptr[r + 1]) - rlo == hi - lo
            if same:
                for e in range(hi - lo):
                    if nxt[rlo + e] != nxt[lo + e] or pbits[rlo + e] != pbits[lo + e]:
                        same = False
                        break
            if same:
                row_of[row] = u
                break
            slot = (slot + 1) & (size - 1)
        if kept > max_outcomes or (
            row == n_rows // 4
            and indptr[n_rows] >= 1_000_000
            and kept > max_fraction * np.float64(indptr[row + 1])
        ):
            return -1, row_of, reps
    return n, row_of, reps


class SharedRows(NamedTuple):
    """The distinct rows of the outcome table's p(s' | s, a), in CSR form.

    ``row_of[s * A + a]`` is the distinct row holding p(. | s, a) (rows of terminal
    states and of unavailable actions share the empty row).
    """

    indptr: np.ndarray
    next_states: np.ndarray
    probs: np.ndarray
    row_of: np.ndarray


#: Look for shared rows only when the non-empty rows hold at least this many outcomes
#: on average (on shorter rows the per-row work dominates and the saving is small).
SHARED_MIN_ROW = 4
#: Use them only when the distinct rows hold at most this fraction of the outcomes.
SHARED_MAX_FRACTION = 0.5

_SHARED: weakref.WeakKeyDictionary[Any, SharedRows | None] = weakref.WeakKeyDictionary()


def shared_rows(mdp: Any) -> SharedRows | None:
    """The distinct rows of p(s' | s, a) when few enough are distinct, else None.

    Found once per model (one pass over the outcome table with a hash table, rows
    compared exactly) and kept with it; None when rows are short (fewer than
    :data:`SHARED_MIN_ROW` outcomes on average over the non-empty rows) or when the
    distinct rows hold more than :data:`SHARED_MAX_FRACTION` of the outcomes.
    """
    if mdp in _SHARED:
        return _SHARED[mdp]
    found: SharedRows | None = None
    n_rows = int(np.count_nonzero(mdp.indptr[1:] != mdp.indptr[:-1]))
    if mdp.n_outcomes >= SHARED_MIN_ROW * n_rows:
        n, row_of, reps = _distinct_rows(
            mdp.indptr,
            mdp.next_states,
            mdp.probs.view(np.uint64),
            SHARED_MAX_FRACTION,
        )
        if n >= 0:
            reps = reps[:n]
            lengths = (mdp.indptr[reps + 1] - mdp.indptr[reps]).astype(np.int64)
            indptr = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(lengths, out=indptr[1:])
            take = np.repeat(mdp.indptr[reps].astype(np.int64) - indptr[:-1], lengths)
            take += np.arange(int(indptr[-1]), dtype=np.int64)
            found = SharedRows(indptr, mdp.next_states[take], mdp.probs[take], row_of)
    _SHARED[mdp] = found
    return found


@njit(cache=True, nogil=True)
def _dense_policy_system(
    indptr: Any, nxt: Any, probs: Any, n_actions: int, act: Any, terminal: Any, gamma: float, M: Any
) -> None:  # pragma: no cover - compiled
    # M = I - gamma P_pi, dense, for a deterministic policy (rows of terminal states: v = 0).
    for s in range(terminal.shape[0]):
        M[s, s] += 1.0
        if terminal[s]:
            continue
        row = s * n_actions + act[s]
        for k in range(np.uint64(indptr[row]), np.uint64(indptr[row + 1])):
            M[s, np.uint64(nxt[k])] -= gamma * probs[k]


def dense_policy_system(mdp: Any, actions: np.ndarray, gamma: float) -> np.ndarray:
    """The dense (S, S) matrix I - gamma P_pi of a deterministic policy, from the outcome table.

    Rows of terminal states are those of the identity (v(s) = 0 there).
    """
    M = np.zeros((mdp.n_states, mdp.n_states))
    _dense_policy_system(
        mdp.indptr,
        mdp.next_states,
        mdp.probs,
        mdp.n_actions,
        np.ascontiguousarray(actions, dtype=np.int64),
        mdp.terminal,
        gamma,
        M,
    )
    return M


@njit(cache=True, nogil=True)
def _component_solve(
    indptr: Any,
    nxt: Any,
    probs: Any,
    row_of: Any,
    gamma: float,
    b: Any,
    x: Any,
    max_block: int,
) -> int:  # pragma: no cover - compiled
    # Solve x = b + gamma P x, where state s's row of P is row ``row_of[s]`` of the CSR
    # arrays (-1: no row, x(s) = 0), one strongly connected component of P's graph at a
    # time. Tarjan's algorithm (iterative) closes each component after every component
    # it can reach, so its successors outside it are solved already: a single state
    # with its self-loop solved exactly, x(s) = (b(s) + gamma sum_{s' != s} p x(s')) /
    # (1 - gamma p(s|s)); a larger component by a dense LU of I - gamma P_CC with the
    # solved successors moved to the right-hand side. Returns the largest component's
    # size, or -1 if a component is larger than ``max_block`` or a state only loops on
    # itself at gamma = 1 (x is then incomplete).
    #
    # index[s]: -1 before s is visited, its visit number while it is on the stack, and
    # S (larger than any visit number) once its component is closed, so one load and
    # one comparison per edge tell all three apart. Self-loops need no test (index[u]
    # is never below low[u]); an entry of probability 0 is an edge like any other (a
    # coarser split, as exact).
    S = row_of.shape[0]
    done = S
    index = np.full(S, -1, dtype=np.int64)
    low = np.empty(S, dtype=np.int64)
    stack = np.empty(S, dtype=np.int64)
    call = np.empty(S, dtype=np.int64)
    edge = np.empty(S, dtype=np.int64)
    local = np.empty(0, dtype=np.int64)  # position in its component, for dense blocks
    top = 0
    counter = 0
    largest = 0
    for root in range(S):
        if index[root] >= 0:
            continue
        depth = 0
        u = np.int64(root)
        while True:
            if index[u] < 0:  # enter u
                index[u] = counter
                low[u] = counter
                counter += 1
                stack[top] = u
                top += 1
                call[depth] = u
                edge[depth] = indptr[row_of[u]] if row_of[u] >= 0 else 0
                depth += 1
            u = call[depth - 1]
            r = row_of[u]
            end = np.int64(indptr[r + 1]) if r >= 0 else 0
            k = np.int64(edge[depth - 1])
            low_u = low[u]
            descend = np.int64(-1)
            while k < end:
                w = np.int64(nxt[k])
                k += 1
                iw = index[w]
                if iw < 0:
                    descend = w
                    break
                if iw < low_u:
                    low_u = iw
            low[u] = low_u
            if descend >= 0:
                edge[depth - 1] = k
                u = descend
                continue
            # u is finished: close its component if it is the component's root
            if low_u == index[u]:
                first = top - 1
                while stack[first] != u:
                    first -= 1
                n = top - first
                largest = max(largest, n)
                if n == 1:
                    if r >= 0:
                        acc, stay = _split_row(indptr, nxt, probs, r, u, x)
                        den = 1.0 - gamma * stay
                        if not den > 1e-12:
                            return -1
                        x[u] = (b[u] + gamma * acc) / den
                    else:
                        x[u] = 0.0
                else:
                    if n > max_block:
                        return -1
                    if local.shape[0] == 0:
                        local = np.full(S, -1, dtype=np.int64)
                    for i in range(n):
                        local[stack[first + i]] = i
                    M = np.zeros((n, n))
                    rhs = np.empty(n)
                    for i in range(n):
                        s = stack[first + i]
                        M[i, i] += 1.0
                        rhs[i] = b[s]
                        rs = row_of[s]
                        for kk in range(np.int64(indptr[rs]), np.int64(indptr[rs + 1])):
                            j = np.int64(nxt[kk])
                            if local[j] >= 0:
                                M[i, local[j]] -= gamma * probs[kk]
                            else:
                                rhs[i] += gamma * probs[kk] * x[j]
                    sol = np.linalg.solve(M, rhs)
                    for i in range(n):
                        s = stack[first + i]
                        x[s] = sol[i]
                        local[s] = -1
                for i in range(first, top):
                    index[stack[i]] = done
                top = first
            depth -= 1
            if depth == 0:
                break
            parent = call[depth - 1]
            if low_u < low[parent]:
                low[parent] = low_u
            u = parent
    return largest


def dense_block_max(n_bytes: int) -> int:
    """The largest component :func:`solve_by_components` may solve by a dense LU.

    Its n x n matrix is no larger than the model (``n_bytes``), and n is at most 3,000.
    """
    return int(min(3000, math.isqrt(max(int(n_bytes), 0) // 8)))


def solve_by_components(
    indptr: np.ndarray,
    nxt: np.ndarray,
    probs: np.ndarray,
    row_of: np.ndarray,
    b: np.ndarray,
    gamma: float,
    max_block: int,
) -> tuple[np.ndarray, int] | None:
    """Solve x = b + gamma P x one strongly connected component of P's graph at a time.

    State s's row of P is row ``row_of[s]`` of the CSR arrays (``indptr``, ``nxt``,
    ``probs``); ``row_of[s] = -1`` marks a state without a row (x(s) = 0). Ordering the
    components so that each comes after every component it can reach makes I - gamma P
    block triangular: a component of one state is solved exactly with its self-loop,
    x(s) = [b(s) + gamma sum_{s' != s} p(s'|s) x(s')] / (1 - gamma p(s|s)), a larger one
    C by a dense LU of I - gamma P_CC with its solved successors on the right-hand side.
    An acyclic graph (a proper policy that heads for the goal) is one back-substitution
    pass; an inventory policy, whose orders only cycle through the low stock levels, a
    small dense block and a back-substitution. The components come from Tarjan's
    algorithm in one pass over the rows.

    Returns:
        x and the largest component's size, or None if a component has more than
        ``max_block`` states or a state only loops on itself at gamma = 1.
    """
    x = np.zeros(row_of.shape[0])
    largest = _component_solve(
        indptr,
        nxt,
        probs,
        np.ascontiguousarray(row_of, dtype=np.int64),
        gamma,
        np.ascontiguousarray(b, dtype=np.float64),
        x,
        int(max_block),
    )
    return None if largest < 0 else (x, int(largest))


def small_components(
    indptr: np.ndarray, nxt: np.ndarray, probs: np.ndarray, row_of: np.ndarray, n_bytes: int
) -> int | None:
    """The largest strongly connected component of a policy's graph, if all are small.

    Small: each fits :func:`dense_block_max` (``n_bytes``, the model's size) and the
    largest one's dense LU, n^3 / 3 multiply-adds, costs no more than one pass over the
    policy's rows, so that exact evaluation by components (:func:`solve_by_components`)
    costs about two passes over the rows. None otherwise. The graph is that of
    ``row_of`` as in :func:`solve_by_components` (found by solving with b = 0).
    """
    rows = np.asarray(row_of, dtype=np.int64)
    live = rows[rows >= 0]
    entries = int((indptr[live + 1] - indptr[live]).sum())
    cheap = 1  # the largest n with n^3 <= 3 * entries (the search stops past it)
    while (cheap + 1) ** 3 <= 3 * entries:
        cheap += 1
    found = solve_by_components(
        indptr,
        nxt,
        probs,
        rows,
        np.zeros(rows.shape[0]),
        0.5,
        min(dense_block_max(n_bytes), cheap),
    )
    return None if found is None else found[1]


def component_solver_name(largest: int, n_states: int) -> str:
    """The ``solver`` reported for a solve by strongly connected components.

    One component of every state is a dense LU of the whole system; components of one
    state each, a back-substitution.
    """
    if largest <= 1:
        return "direct (back-substitution)"
    if largest == n_states:
        return "direct (dense LU)"
    return f"direct (components: back-substitution, dense LU up to {largest} states)"


def component_policy_solve(
    mdp: Any, actions: np.ndarray, b: np.ndarray, gamma: float, max_block: int
) -> tuple[np.ndarray, int] | None:
    """:func:`solve_by_components` for a deterministic policy on the outcome table.

    Solves v = b + gamma P_pi v with v = 0 on terminal states; the rows of P_pi are the
    outcome table's rows (s, pi(s)).
    """
    row_of = np.arange(mdp.n_states, dtype=np.int64) * mdp.n_actions + np.asarray(
        actions, dtype=np.int64
    )
    row_of[mdp.terminal] = -1
    return solve_by_components(mdp.indptr, mdp.next_states, mdp.probs, row_of, b, gamma, max_block)
