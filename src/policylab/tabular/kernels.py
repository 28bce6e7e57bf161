"""Conventions and building blocks of the compiled (numba) tabular kernels.

Every tabular learner has a fast path on a :class:`~policylab.FiniteMDP`: episodes are
simulated from the MDP's outcome table and the updates applied inside ``@njit``
kernels. The pieces here are shared by every algorithm (Monte Carlo, TD family):

* **Randomness.** A kernel never touches a global RNG. ``seed`` (int, Generator or
  None) -> :func:`rng_states` -> one xoshiro256+ state (4 x uint64) per run, carried
  in an array that the kernel advances in place (so a run can be split into chunks
  between checkpoints and still give the same numbers). Same seed, same result.
* **The model.** :class:`KernelMDP` holds the arrays a kernel reads: ``indptr``,
  ``next_states``, ``probs`` (and their running sums ``cdf``), ``rewards`` (row
  ``s * A + a``), ``terminal``,
  ``action_mask``, ``initial_cdf``. :func:`sample_next` draws one transition,
  :func:`sample_start` a start state. A draw with one possible outcome consumes no
  random number, so on a deterministic MDP only the policy uses the RNG (this is what
  lets the general Gymnasium path agree with the kernel exactly).
* **Actions.** :func:`sample_action` draws from a policy row pi(. | s);
  :func:`epsilon_greedy_action` is epsilon-greedy on a Q row over A(s) with random
  tie-breaking; :func:`greedy_action` is the first best available action.
* **Episodes.** :func:`generate_episode` fills :class:`EpisodeBuffers` S_0..S_T,
  A_0..A_{T-1}, R_1..R_T and b(A_t | S_t), with the actions of a :class:`Behaviour`
  (:func:`choose_action`: a fixed policy table or epsilon-greedy on the current Q,
  optionally from an exploring start). A kernel reads the model as a :class:`Model`.

Every function here is also callable from plain Python (numba dispatches), which is
how the general path over a Gymnasium env reuses the same action choice and update
rules. The helpers of the step loops (the RNG draws, :func:`sample_next`,
:func:`epsilon_greedy_at`) are inlined into the loops (``inline="always"``): called as
functions, every array argument cost a reference-count increment and decrement, which
was most of the time of a step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import numba as nb
import numpy as np
from numba import types
from numba.extending import overload

from policylab.tabular.schedules import schedule_value

if TYPE_CHECKING:
    from numba.core.dispatcher import Dispatcher
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "EPSILON_GREEDY",
    "FIXED_POLICY",
    "Behaviour",
    "EpisodeBuffers",
    "KernelMDP",
    "Model",
    "behaviour_epsilon",
    "choose_action",
    "choose_action_at",
    "env_reset",
    "env_step",
    "episode_buffers",
    "episode_loop",
    "epsilon_greedy_action",
    "epsilon_greedy_at",
    "epsilon_greedy_prob",
    "exploring_start_state",
    "generate_episode",
    "greedy_action",
    "outcome_cdf",
    "rand_below",
    "rand_uniform",
    "rng_states",
    "sample_action",
    "sample_next",
    "sample_start",
    "seed_states",
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
    return _usable(rng.integers(0, 2**64 - 1, size=(n_runs, 4), dtype=np.uint64, endpoint=True))


def seed_states(seeds: Sequence[int]) -> NDArray[np.uint64]:
    """``rng_states(seed, 1)[0]`` of each integer seed, stacked (R, 4): one run per seed.

    Each seed's words come from the PCG64 that ``numpy.random.default_rng(seed)`` would
    wrap, read raw (a full-range uint64 draw of ``integers`` is the raw output), without
    building a Generator per seed: many seeds are set up in a fraction of the time.
    """
    raw = [np.random.PCG64(s).random_raw(4) for s in seeds]
    return _usable(np.array(raw, dtype=np.uint64).reshape(len(raw), 4))


def _usable(states: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """The states with an all-zero one (which xoshiro cannot leave) replaced."""
    states[np.all(states == 0, axis=1)] = np.uint64(0x9E3779B97F4A7C15)
    return states


_F = TypeVar("_F", bound=Callable[..., object])


def episode_loop(fn: _F) -> Dispatcher[_F]:
    """Compile an episode loop: ``njit(cache=True, nogil=True)`` without reference counting.

    numba counts the references to every array a compiled function holds; each
    array a loop hands to an inlined helper (``epsilon_greedy_at``, ``sample_next``, the
    RNG draws) then costs an atomic increment and decrement of its count at every step,
    which numba cannot prune across the helpers' branches: they were more than half the
    time of a Q-learning step, and four fifths of a Monte Carlo control step on
    FrozenLake 8x8. Compiled without them (numba's ``_nrt=False``), a loop allocates
    nothing (its working memory comes from its caller: the TD loops' ``Tables``, the
    Monte Carlo episode buffers) and only borrows the arrays its caller keeps alive.
    Everything it calls is compiled the same way, so no helper may allocate or return
    a new array.
    """
    no_reference_counting: dict[str, Any] = {"_nrt": False}  # not in numba's stubs
    loop: Dispatcher[_F] = nb.njit(fn, cache=True, nogil=True, **no_reference_counting)
    return loop


@nb.njit(cache=True, nogil=True, inline="always")
def _rotl(x: np.uint64, k: int) -> np.uint64:  # pragma: no cover - compiled
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@nb.njit(cache=True, nogil=True, inline="always")
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


@nb.njit(cache=True, nogil=True, inline="always")
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


@nb.njit(cache=True, nogil=True, inline="always")
def sample_next(
    indptr: NDArray[np.int64],
    cdf: NDArray[np.float64],
    row: int,
    state: NDArray[np.uint64],
) -> int:  # pragma: no cover - compiled
    """The outcome index k of row ``s * A + a`` drawn from p(s', r | s, a).

    One uniform u (none if the row has one outcome), then the first k with u < cdf[k]:
    ``cdf`` is the row's running sum of probabilities (:func:`outcome_cdf`), +inf from
    its last positive outcome on, so that k is the number of entries with u >= cdf[k]
    (a count without a data-dependent branch).
    """
    lo = indptr[row]
    if indptr[row + 1] - lo == 1:
        return lo  # type: ignore[no-any-return]
    u = rand_uniform(state)
    k = lo
    for j in range(lo, indptr[row + 1] - 1):  # counting, not searching: no branch to miss
        k += u >= cdf[j]
    return k  # type: ignore[no-any-return]


@nb.njit(cache=True, nogil=True)
def outcome_cdf(
    indptr: NDArray[np.int64], probs: NDArray[np.float64]
) -> NDArray[np.float64]:  # pragma: no cover - compiled
    """Each outcome row's running sum of probabilities, +inf from its last positive one.

    The sums are those :func:`_draw_from` accumulates (zeros add nothing), so
    :func:`sample_next` picks exactly the outcome the running-sum loop would for the
    same uniform, including the last positive outcome when rounding leaves u above
    the row's total.
    """
    cdf = np.zeros(probs.shape[0])
    for row in range(indptr.shape[0] - 1):
        lo, hi = indptr[row], indptr[row + 1]
        acc = 0.0
        last = -1
        for k in range(lo, hi):
            if probs[k] > 0.0:
                acc += probs[k]
                last = k
            cdf[k] = acc
        if last >= 0:
            cdf[last:hi] = np.inf
    return cdf


@nb.njit(cache=True, nogil=True)
def _draw_index(
    weights: NDArray[np.float64], state: NDArray[np.uint64]
) -> int:  # pragma: no cover - compiled
    """An index drawn with probability weights[i]; no draw if only one weight is positive."""
    n = weights.shape[0]
    first = -1
    count = 0
    for i in range(n):
        if weights[i] > 0.0:
            count += 1
            if first < 0:
                first = i
    if count == 1:
        return first
    return _draw_from(weights, 0, n, state)


@nb.njit(cache=True, nogil=True)
def sample_start(
    initial: NDArray[np.float64], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """A start state index drawn from the start distribution (no draw if it is one state)."""
    return _draw_index(initial, state)


@nb.njit(cache=True, nogil=True)
def sample_action(
    pi_row: NDArray[np.float64], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """An action index drawn from pi(. | s) (no draw if the policy is deterministic there)."""
    return _draw_index(pi_row, state)


@nb.njit(cache=True, nogil=True)
def _n_available(mask_row: NDArray[np.bool_]) -> int:  # pragma: no cover - compiled
    n = 0
    for a in range(mask_row.shape[0]):
        if mask_row[a]:
            n += 1
    return n


@nb.njit(cache=True, nogil=True, inline="always")
def _uniform_at(
    mask: NDArray[np.bool_], s: int, state: NDArray[np.uint64]
) -> int:  # pragma: no cover - compiled
    """A uniform action of A(s), row ``s`` of the (S, A) mask (one draw)."""
    n_actions = mask.shape[1]
    n_avail = 0
    for a in range(n_actions):
        n_avail += mask[s, a]
    k = rand_below(state, n_avail)
    for a in range(n_actions):
        if mask[s, a]:
            if k == 0:
                return a
            k -= 1
    return -1


@nb.njit(cache=True, nogil=True)
def uniform_action(
    mask_row: NDArray[np.bool_], state: NDArray[np.uint64]
) -> int:  # pragma: no cover
    """A uniform action of A(s) (one draw)."""
    n = mask_row.shape[0]
    return _uniform_at(np.ascontiguousarray(mask_row).reshape((1, n)), 0, state)


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


@nb.njit(cache=True, nogil=True, inline="always")
def epsilon_greedy_at(
    q: NDArray[np.float64],
    mask: NDArray[np.bool_],
    s: int,
    epsilon: float,
    state: NDArray[np.uint64],
) -> int:  # pragma: no cover - compiled
    """Epsilon-greedy on Q(s, .) over A(s): uniform with probability epsilon, else greedy.

    ``q`` and ``mask`` are whole (S, A) tables and ``s`` the row (indexing them here
    rather than passing row views keeps the compiled step loops free of array
    temporaries). Draws: one uniform u (skipped when epsilon is 0); if u < epsilon a
    uniform action of A(s); else a greedy action, ties broken uniformly (one more draw
    only if tied).
    """
    n_actions = q.shape[1]
    if epsilon > 0.0 and rand_uniform(state) < epsilon:
        return _uniform_at(mask, s, state)
    best_q = -np.inf
    for a in range(n_actions):  # max over A(s), written to compile to selects, not branches
        x = q[s, a]
        best_q = x if (mask[s, a] and x > best_q) else best_q
    n_best = 0
    first = -1
    for a in range(n_actions):
        hit = mask[s, a] and q[s, a] == best_q
        n_best += hit
        first = a if (hit and first < 0) else first
    if n_best == 1:  # one greedy action: no tie to break
        return first
    k = rand_below(state, n_best)
    for a in range(n_actions):
        if mask[s, a] and q[s, a] == best_q:
            if k == 0:
                return a
            k -= 1
    return -1


@nb.njit(cache=True, nogil=True)
def epsilon_greedy_action(
    q_row: NDArray[np.float64],
    mask_row: NDArray[np.bool_],
    epsilon: float,
    state: NDArray[np.uint64],
) -> int:  # pragma: no cover - compiled
    """:func:`epsilon_greedy_at` on one row Q(s, .) and A(s) (the same draws)."""
    n = q_row.shape[0]
    return epsilon_greedy_at(
        np.ascontiguousarray(q_row).reshape((1, n)),
        np.ascontiguousarray(mask_row).reshape((1, n)),
        0,
        epsilon,
        state,
    )


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


class Model(NamedTuple):
    """The arrays of a FiniteMDP that a kernel samples (a :class:`KernelMDP`, as a tuple).

    ``indptr``, ``next_states``, ``cdf``, ``rewards``: the outcome table (row
    ``s * A + a``); ``terminal``; ``initial``: the start distribution; ``mask``: A(s).
    On the general path (a Gymnasium env steps instead) the first six are empty arrays
    of the same types and ``mask`` is A(s).
    """

    indptr: Any
    next_states: Any
    cdf: Any
    rewards: Any
    terminal: Any
    initial: Any
    mask: Any


class Behaviour(NamedTuple):
    """How an episode's actions are chosen (:func:`choose_action`).

    ``kind``: :data:`FIXED_POLICY` (draw from the (S, A) table ``pi``) or
    :data:`EPSILON_GREEDY` (epsilon-greedy in the current Q). ``epsilon``: the schedule's
    params, read at the episode number, or with ``by_state`` at the visit count + 1 of
    the current state (GLIE state by state, capped at 1). ``exploring_starts``: S_0 a
    uniform non-terminal state and A_0 a uniform action of A(S_0), then the policy.
    """

    kind: int
    pi: Any
    epsilon: Any
    by_state: bool
    exploring_starts: bool


class EpisodeBuffers(NamedTuple):
    """One episode's buffers, with room for ``len(a)`` steps.

    ``s[0..T]`` = S_0..S_T, ``a[t]`` = A_t, ``r[t]`` = R_{t+1}, ``b[t]`` = b(A_t | S_t),
    the probability with which A_t was chosen.
    """

    s: Any
    a: Any
    r: Any
    b: Any


def episode_buffers(max_steps: int) -> EpisodeBuffers:
    """Empty :class:`EpisodeBuffers` for episodes of at most ``max_steps`` steps."""
    return EpisodeBuffers(
        np.zeros(max_steps + 1, dtype=np.int64),
        np.zeros(max_steps, dtype=np.int64),
        np.zeros(max_steps),
        np.zeros(max_steps),
    )


@nb.njit(cache=True, nogil=True)
def behaviour_epsilon(
    by_state: bool, epsilon_params: NDArray[np.float64], epsilon: float, visits: float
) -> float:  # pragma: no cover - compiled
    """The exploration rate in a state: the episode's ``epsilon``, or by state visits.

    With ``by_state``: the schedule at the state's visit count + 1, capped at 1 (GLIE
    state by state).
    """
    if by_state:
        return min(1.0, schedule_value(epsilon_params, visits + 1.0))
    return epsilon


@nb.njit(cache=True, nogil=True, inline="always")
def choose_action_at(
    kind: int,
    explore: bool,
    pi_row: NDArray[np.float64],
    q: NDArray[np.float64],
    mask: NDArray[np.bool_],
    s: int,
    epsilon: float,
    rng: NDArray[np.uint64],
) -> tuple[int, float]:  # pragma: no cover - compiled
    """(A_t, b(A_t | S_t)): a behaviour's action in state ``s`` and its probability.

    ``explore``: an exploring start's first step (a uniform action of A(s)); else
    ``kind`` :data:`FIXED_POLICY` draws from ``pi_row`` = pi(. | S_t) and
    :data:`EPSILON_GREEDY` is epsilon-greedy in Q(S_t, .). ``q`` and ``mask`` are the
    whole (S, A) tables, as in :func:`epsilon_greedy_at`, so that a compiled episode
    loop makes no array temporaries.
    """
    if explore:
        return _uniform_at(mask, s, rng), 1.0 / _n_available(mask[s])
    if kind == FIXED_POLICY:
        a = sample_action(pi_row, rng)
        return a, pi_row[a]
    a = epsilon_greedy_at(q, mask, s, epsilon, rng)
    return a, epsilon_greedy_prob(q[s], mask[s], epsilon, a)


@nb.njit(cache=True, nogil=True)
def choose_action(
    kind: int,
    explore: bool,
    pi_row: NDArray[np.float64],
    q_row: NDArray[np.float64],
    mask_row: NDArray[np.bool_],
    epsilon: float,
    rng: NDArray[np.uint64],
) -> tuple[int, float]:  # pragma: no cover - compiled
    """:func:`choose_action_at` on one row Q(s, .) and A(s) (the same draws)."""
    n = q_row.shape[0]
    return choose_action_at(
        kind,
        explore,
        pi_row,
        np.ascontiguousarray(q_row).reshape((1, n)),
        np.ascontiguousarray(mask_row).reshape((1, n)),
        0,
        epsilon,
        rng,
    )


@episode_loop
def generate_episode(
    model: Model,
    behaviour: Behaviour,
    q: NDArray[np.float64],
    epsilon: float,
    visits: NDArray[np.float64],
    rng: NDArray[np.uint64],
    buf: EpisodeBuffers,
) -> tuple[int, bool]:  # pragma: no cover - compiled
    """Simulate one episode on the model into ``buf``; return (its length T, truncated).

    The episode stops at a terminal state, or is truncated when the buffers
    (``len(buf.a)`` steps) are full. Actions come from :func:`choose_action` with
    ``q`` (S, A) the current action values and ``epsilon`` the episode's rate
    (``visits`` (S,) the state visit counts for a rate by state).
    """
    mask, terminal = model.mask, model.terminal
    n_actions = mask.shape[1]
    max_steps = buf.a.shape[0]
    if behaviour.exploring_starts:
        s = exploring_start_state(terminal, rng)
    else:
        s = sample_start(model.initial, rng)
    buf.s[0] = s
    t = 0
    while not terminal[s]:
        if t >= max_steps:
            return t, True
        eps = behaviour_epsilon(behaviour.by_state, behaviour.epsilon, epsilon, visits[s])
        explore = behaviour.exploring_starts and t == 0
        a, b = choose_action_at(behaviour.kind, explore, behaviour.pi[s], q, mask, s, eps, rng)
        k = sample_next(model.indptr, model.cdf, s * n_actions + a, rng)
        buf.a[t] = a
        buf.b[t] = b
        buf.r[t] = model.rewards[k]
        s = model.next_states[k]
        t += 1
        buf.s[t] = s
    return t, False


# ---------------------------------------------------------------------------- the environment
def env_reset(env: Any, model: Model, rng: Any) -> int:
    """S_0: ``env.reset()`` (general path) or a draw from the model's start distribution.

    On the compiled path ``env`` is None and ``model`` is sampled with the run's RNG.
    """
    return int(env.reset())


def env_step(env: Any, model: Model, s: int, a: int, rng: Any) -> tuple[int, float, bool, bool]:
    """(S_{t+1}, R_{t+1}, terminated, truncated) after A_t = a in S_t = s.

    General path: ``env.step(a)``. Compiled path (``env`` None): one outcome of row
    ``s * A + a`` of the model's outcome table, drawn with :func:`sample_next` (inlined
    into the episode loops).
    """
    return env.step(a)  # type: ignore[no-any-return]


@overload(env_reset, inline="always")
def _env_reset_model(env, model, rng):  # type: ignore[no-untyped-def]  # pragma: no cover
    if isinstance(env, types.NoneType):
        return lambda env, model, rng: sample_start(model.initial, rng)
    return None


@overload(env_step, inline="always")
def _env_step_model(env, model, s, a, rng):  # type: ignore[no-untyped-def]  # pragma: no cover
    if isinstance(env, types.NoneType):

        def impl(env, model, s, a, rng):  # type: ignore[no-untyped-def]
            o = sample_next(model.indptr, model.cdf, s * model.mask.shape[1] + a, rng)
            s2 = model.next_states[o]
            return s2, model.rewards[o], model.terminal[s2], False

        return impl
    return None


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
    cdf: NDArray[np.float64]
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
            outcome_cdf(writable(mdp.indptr, np.int64), writable(mdp.probs, np.float64)),
            writable(mdp.rewards, np.float64),
            writable(mdp.terminal, np.bool_),
            writable(mdp.action_mask, np.bool_),
            writable(mdp.initial, np.float64),
            float(mdp.gamma if gamma is None else gamma),
        )
