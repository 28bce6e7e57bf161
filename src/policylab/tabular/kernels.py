"""Conventions and building blocks of the compiled (numba) tabular kernels.

Every tabular learner has a fast path on a :class:`~policylab.FiniteMDP`: episodes are
simulated from the MDP's outcome table and the updates applied inside ``@njit``
kernels. The pieces here are shared by every algorithm (Monte Carlo, TD family):

* **Randomness.** A kernel never touches a global RNG. ``seed`` (int, Generator or
  None) -> :func:`rng_states` -> one xoshiro256+ state (4 x uint64) per run, carried
  in an array that the kernel advances in place (so a run can be split into chunks
  between checkpoints and still give the same numbers). Same seed, same result.
* **The model.** :class:`KernelMDP` holds the arrays a kernel reads: ``indptr``,
  ``next_states``, ``probs``, ``rewards`` (row ``s * A + a``), ``terminal``,
  ``action_mask``, ``initial_cdf``. :func:`sample_next` draws one transition,
  :func:`sample_start` a start state. A draw with one possible outcome consumes no
  random number, so on a deterministic MDP only the policy uses the RNG (this is what
  lets the general Gymnasium path agree with the kernel exactly).
* **Actions.** :func:`sample_action` draws from a policy row pi(. | s);
  :func:`epsilon_greedy_action` is epsilon-greedy on a Q row over A(s) with random
  tie-breaking; :func:`greedy_action` is the first best available action.
* **Episodes.** :func:`generate_episode` fills preallocated buffers S_0..S_T,
  A_0..A_{T-1}, R_1..R_T and b(A_t | S_t), following either a fixed policy table or
  epsilon-greedy on the current Q, optionally from an exploring start.

Every function here is also callable from plain Python (numba dispatches), which is
how the general path over a Gymnasium env reuses the same action choice and update
rules.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba as nb
import numpy as np

from policylab.tabular.schedules import schedule_value

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "EPSILON_GREEDY",
    "FIXED_POLICY",
    "KernelMDP",
    "epsilon_greedy_action",
    "epsilon_greedy_prob",
    "exploring_start_state",
    "generate_episode",
    "greedy_action",
    "rand_below",
    "rand_uniform",
    "rng_states",
    "sample_action",
    "sample_next",
    "sample_start",
    "uniform_action",
    "writable",
]

#: ``policy_kind`` codes of :func:`generate_episode`.
FIXED_POLICY, EPSILON_GREEDY = 0, 1

_U1 = np.uint64(1)


def rng_states(seed: int | np.random.Generator | None, n_runs: int = 1) -> NDArray[np.uint64]:
    """Kernel RNG states (n_runs, 4) uint64 from a seed: seed -> Generator -> per-run words.

    The words come from ``numpy.random.default_rng(seed)`` (so a Generator passed in is
    advanced, and an int seed always gives the same states); an all-zero state (which
    xoshiro cannot leave) is replaced.
    """
    rng = np.random.default_rng(seed)
    st = rng.integers(0, 2**64 - 1, size=(n_runs, 4), dtype=np.uint64, endpoint=True)
    st[np.all(st == 0, axis=1)] = np.uint64(0x9E3779B97F4A7C15)
    return st


@nb.njit(cache=True, nogil=True)
def _rotl(x: np.uint64, k: int) -> np.uint64:  # pragma: no cover - compiled
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@nb.njit(cache=True, nogil=True)
def rand_uniform(state: NDArray[np.uint64]) -> float:  # pragma: no cover - compiled
    """A uniform float in [0, 1) from a xoshiro256+ state (advanced in place)."""
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    result = s0 + s3
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, 45)
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    return float(result >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True, nogil=True)
def rand_below(state: NDArray[np.uint64], n: int) -> int:  # pragma: no cover - compiled
    """A uniform integer in [0, n)."""
    k = int(rand_uniform(state) * n)
    return k if k < n else n - 1


@nb.njit(cache=True, nogil=True)
def _draw_from(
    weights: NDArray[np.float64], lo: int, hi: int, state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """Index k in [lo, hi) drawn with probability weights[k]; no draw if hi - lo == 1."""
    if hi - lo == 1:
        return lo
    u = rand_uniform(state)
    acc = 0.0
    last = lo
    for k in range(lo, hi):
        w = weights[k]
        if w > 0.0:
            last = k
            acc += w
            if u < acc:
                return k
    return last


@nb.njit(cache=True, nogil=True)
def sample_next(
    indptr: NDArray[np.int64],
    probs: NDArray[np.float64],
    row: int,
    state: NDArray[np.uint64],
) -> int:  # pragma: no cover - compiled
    """The outcome index k of row ``s * A + a`` drawn from p(s', r | s, a)."""
    return _draw_from(probs, indptr[row], indptr[row + 1], state)


@nb.njit(cache=True, nogil=True)
def sample_start(
    initial: NDArray[np.float64], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """A start state index drawn from the start distribution (no draw if it is one state)."""
    n = initial.shape[0]
    first = -1
    count = 0
    for s in range(n):
        if initial[s] > 0.0:
            count += 1
            if first < 0:
                first = s
    if count == 1:
        return first
    return _draw_from(initial, 0, n, state)


@nb.njit(cache=True, nogil=True)
def sample_action(
    pi_row: NDArray[np.float64], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """An action index drawn from pi(. | s) (no draw if the policy is deterministic there)."""
    n = pi_row.shape[0]
    first = -1
    count = 0
    for a in range(n):
        if pi_row[a] > 0.0:
            count += 1
            if first < 0:
                first = a
    if count == 1:
        return first
    return _draw_from(pi_row, 0, n, state)


@nb.njit(cache=True, nogil=True)
def _n_available(mask_row: NDArray[np.bool_]) -> int:  # pragma: no cover - compiled
    n = 0
    for a in range(mask_row.shape[0]):
        if mask_row[a]:
            n += 1
    return n


@nb.njit(cache=True, nogil=True)
def uniform_action(
    mask_row: NDArray[np.bool_], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """A uniform action of A(s) (one draw)."""
    k = rand_below(state, _n_available(mask_row))
    for a in range(mask_row.shape[0]):
        if mask_row[a]:
            if k == 0:
                return a
            k -= 1
    return -1


@nb.njit(cache=True, nogil=True)
def exploring_start_state(
    terminal: NDArray[np.bool_], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """A uniform non-terminal state (one draw): S_0 of an exploring start."""
    n_live = 0
    for s in range(terminal.shape[0]):
        if not terminal[s]:
            n_live += 1
    k = rand_below(state, n_live)
    for s in range(terminal.shape[0]):
        if not terminal[s]:
            if k == 0:
                return s
            k -= 1
    return -1


@nb.njit(cache=True, nogil=True)
def greedy_action(
    q_row: NDArray[np.float64], mask_row: NDArray[np.bool_]
) -> int:  # pragma: no cover
    """argmax_a Q(s, a) over A(s); the first best action on ties."""
    best = -1
    best_q = 0.0
    for a in range(q_row.shape[0]):
        if mask_row[a] and (best < 0 or q_row[a] > best_q):
            best = a
            best_q = q_row[a]
    return best


@nb.njit(cache=True, nogil=True)
def epsilon_greedy_action(
    q_row: NDArray[np.float64],
    mask_row: NDArray[np.bool_],
    epsilon: float,
    state: NDArray[np.uint64],
) -> int:  # pragma: no cover - compiled
    """Epsilon-greedy on Q(s, .) over A(s): uniform with probability epsilon, else greedy.

    Draws: one uniform u (skipped when epsilon is 0); if u < epsilon a uniform action
    of A(s); else a greedy action, ties broken uniformly (one more draw only if tied).
    """
    if epsilon > 0.0 and rand_uniform(state) < epsilon:
        return uniform_action(mask_row, state)
    best_q = -np.inf
    n_best = 0
    for a in range(q_row.shape[0]):
        if mask_row[a]:
            if q_row[a] > best_q:
                best_q = q_row[a]
                n_best = 1
            elif q_row[a] == best_q:
                n_best += 1
    k = 0 if n_best == 1 else rand_below(state, n_best)
    for a in range(q_row.shape[0]):
        if mask_row[a] and q_row[a] == best_q:
            if k == 0:
                return a
            k -= 1
    return -1


@nb.njit(cache=True, nogil=True)
def epsilon_greedy_prob(
    q_row: NDArray[np.float64], mask_row: NDArray[np.bool_], epsilon: float, action: int
) -> float:  # pragma: no cover - compiled
    """pi(a | s) of the epsilon-greedy policy of :func:`epsilon_greedy_action` (ties shared)."""
    n_avail = 0
    best_q = -np.inf
    for a in range(q_row.shape[0]):
        if mask_row[a]:
            n_avail += 1
            if q_row[a] > best_q:
                best_q = q_row[a]
    n_best = 0
    for a in range(q_row.shape[0]):
        if mask_row[a] and q_row[a] == best_q:
            n_best += 1
    p = epsilon / n_avail
    if q_row[action] == best_q:
        p += (1.0 - epsilon) / n_best
    return p


@nb.njit(cache=True, nogil=True)
def generate_episode(
    indptr: NDArray[np.int64],
    next_states: NDArray[np.int32],
    probs: NDArray[np.float64],
    rewards: NDArray[np.float64],
    terminal: NDArray[np.bool_],
    mask: NDArray[np.bool_],
    initial: NDArray[np.float64],
    policy_kind: int,
    pi: NDArray[np.float64],
    q: NDArray[np.float64],
    epsilon: float,
    exploring_start: bool,
    rng: NDArray[np.uint64],
    buf_s: NDArray[np.int64],
    buf_a: NDArray[np.int64],
    buf_r: NDArray[np.float64],
    buf_b: NDArray[np.float64],
    eps_params: NDArray[np.float64],
    visits: NDArray[np.float64],
) -> int:  # pragma: no cover - compiled
    """Simulate one episode into the buffers; return its length T (negative if truncated).

    ``buf_s[0..T]`` = S_0..S_T, ``buf_a[0..T-1]`` = A_0..A_{T-1}, ``buf_r[t]`` =
    R_{t+1}, ``buf_b[t]`` = b(A_t | S_t), the probability with which A_t was chosen.
    The episode stops at a terminal state, or is truncated (returned as -T) when the
    buffers (``len(buf_a)`` steps) are full.

    Args:
        indptr: Outcome table offsets (row ``s * A + a``).
        next_states: Next state of each outcome.
        probs: Probability of each outcome.
        rewards: Reward of each outcome.
        terminal: (S,) terminal mask.
        mask: (S, A) A(s).
        initial: (S,) start distribution (ignored with exploring starts).
        policy_kind: ``FIXED_POLICY`` (draw from the table ``pi``) or
            ``EPSILON_GREEDY`` (epsilon-greedy on ``q``).
        exploring_start: Start from a uniform non-terminal state and a uniform action
            of A(S_0) (the exploring-starts assumption), then follow the policy.
        pi: (S, A) policy table (``FIXED_POLICY``).
        q: (S, A) action values (``EPSILON_GREEDY``).
        epsilon: Exploration rate (``EPSILON_GREEDY``).
        rng: The run's RNG state (advanced in place).
        buf_s: (max_steps + 1,) states out.
        buf_a: (max_steps,) actions out.
        buf_r: (max_steps,) rewards out.
        buf_b: (max_steps,) behaviour probabilities out.
        eps_params: With a non-empty ``visits``: the epsilon schedule, evaluated per
            state at its visit count + 1 (GLIE by state, epsilon capped at 1) instead
            of the per-episode ``epsilon``.
        visits: (S,) visit counts for per-state epsilon, or an empty array.
    """
    n_actions = mask.shape[1]
    max_steps = buf_a.shape[0]
    s = exploring_start_state(terminal, rng) if exploring_start else sample_start(initial, rng)
    buf_s[0] = s
    t = 0
    while not terminal[s]:
        if t >= max_steps:
            return -t
        if exploring_start and t == 0:
            a = uniform_action(mask[s], rng)
            b = 1.0 / _n_available(mask[s])
        elif policy_kind == FIXED_POLICY:
            a = sample_action(pi[s], rng)
            b = pi[s, a]
        else:
            eps = epsilon
            if visits.shape[0] > 0:
                eps = min(1.0, schedule_value(eps_params, visits[s] + 1.0))
            a = epsilon_greedy_action(q[s], mask[s], eps, rng)
            b = epsilon_greedy_prob(q[s], mask[s], eps, a)
        k = sample_next(indptr, probs, s * n_actions + a, rng)
        buf_a[t] = a
        buf_b[t] = b
        buf_r[t] = rewards[k]
        s = next_states[k]
        t += 1
        buf_s[t] = s
    return t


def writable(x: Any, dtype: Any) -> NDArray[Any]:
    """A C-contiguous, writable copy of ``x`` in ``dtype``.

    Numba compiles a separate specialization for read-only arrays (a FiniteMDP's and a
    Policy's arrays are read-only), so kernels are always handed writable copies: one
    compiled version per kernel, cached on disk.
    """
    return np.array(x, dtype=dtype, order="C", copy=True)


@dataclass(frozen=True)
class KernelMDP:
    """The arrays of a :class:`FiniteMDP` in the dtypes the kernels take."""

    indptr: NDArray[np.int64]
    next_states: NDArray[np.int32]
    probs: NDArray[np.float64]
    rewards: NDArray[np.float64]
    terminal: NDArray[np.bool_]
    mask: NDArray[np.bool_]
    initial: NDArray[np.float64]
    gamma: float

    @classmethod
    def of(cls, mdp: FiniteMDP, gamma: float | None = None) -> KernelMDP:
        """The kernel view of an MDP (``gamma`` overrides the MDP's own)."""
        return cls(
            writable(mdp.indptr, np.int64),
            writable(mdp.next_states, np.int32),
            writable(mdp.probs, np.float64),
            writable(mdp.rewards, np.float64),
            writable(mdp.terminal, np.bool_),
            writable(mdp.action_mask, np.bool_),
            writable(mdp.initial, np.float64),
            float(mdp.gamma if gamma is None else gamma),
        )
