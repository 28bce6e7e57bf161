"""Random MDPs built directly in sparse form, for tests and benchmarks at any scale."""

from __future__ import annotations

from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.problems.registry import register_problem

__all__ = ["long_chain", "random_mdp", "slip_gridworld"]


def _check_count(name: str, x: Any, minimum: int) -> int:
    if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < minimum:
        raise InvalidArgumentError(f"{name} must be an integer >= {minimum}; got {x!r}")
    return int(x)


def _check_probability(name: str, x: Any, *, open_low: bool = False) -> float:
    try:
        p = float(x)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{name} must be a number in [0, 1); got {x!r}") from None
    if not (0.0 < p < 1.0 if open_low else 0.0 <= p < 1.0):
        low = "(0" if open_low else "[0"
        raise InvalidArgumentError(f"{name} must lie in {low}, 1); got {x!r}")
    return p


def _moves_with_slip(
    target: np.ndarray, slip: np.ndarray, reward: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The outcome table of moves (s, a) -> target[s, a] that stay at s with prob. slip[a].

    ``target`` is (S, A) with -1 on the rows of terminal states (no outcomes); ``slip``
    is (A,). A move into a wall (target == s) or with slip 0 has one outcome; otherwise
    two, the move (1 - slip) and staying put (slip). Every outcome earns ``reward``.
    """
    S, A = target.shape
    own = np.repeat(np.arange(S), A)
    t = target.ravel()
    sl = np.tile(np.asarray(slip, dtype=np.float64), S)
    live = t >= 0
    two = live & (t != own) & (sl > 0)
    counts = np.where(two, 2, np.where(live, 1, 0))
    indptr = np.zeros(S * A + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    K = int(indptr[-1])
    nxt = np.empty(K, dtype=np.int32 if S < 2**31 else np.int64)
    probs = np.empty(K)
    first = indptr[:-1][live]
    nxt[first] = t[live]
    probs[first] = np.where(two[live], 1.0 - sl[live], 1.0)
    second = indptr[:-1][two] + 1
    nxt[second] = own[two]
    probs[second] = sl[two]
    return indptr, nxt, probs, np.full(K, float(reward))


def slip_gridworld(
    size: int = 50, slip: float = 0.1, gamma: float = 0.99, step_reward: float = -1.0
) -> FiniteMDP:
    """A large slippery gridworld: the slow-mixing benchmark of exact planning.

    ``size`` x ``size`` cells (state r * size + c for row r, column c), four moves
    (up, down, left, right); a move succeeds with probability 1 - ``slip`` and leaves
    the agent in place otherwise; a move into the border stays put. Every step earns
    ``step_reward``; the goal, the bottom-right cell, is terminal. The start is the
    top-left cell. With gamma close to 1 values propagate slowly (about one cell per
    synchronous sweep), which makes plain value iteration slow; with gamma = 1 it is a
    stochastic shortest-path problem, v_*(s) = -(Manhattan distance to the goal) /
    (1 - slip) for the default reward.

    Args:
        size: Cells per side, >= 2 (size**2 states; 1000 gives 10^6).
        slip: Probability that a move leaves the agent in place, in [0, 1).
        gamma: Discount rate in [0, 1].
        step_reward: Reward of every step.
    """
    n = _check_count("size", size, 2)
    p = _check_probability("slip", slip)
    S = n * n
    r, c = np.divmod(np.arange(S), n)
    idx = np.arange(S)
    target = np.stack(
        [
            np.where(r > 0, idx - n, idx),
            np.where(r < n - 1, idx + n, idx),
            np.where(c > 0, idx - 1, idx),
            np.where(c < n - 1, idx + 1, idx),
        ],
        axis=1,
    )
    terminal = np.zeros(S, dtype=bool)
    terminal[S - 1] = True
    target[S - 1] = -1
    indptr, nxt, probs, rewards = _moves_with_slip(target, np.full(4, p), step_reward)
    initial = np.zeros(S)
    initial[0] = 1.0
    return FiniteMDP(
        states=tuple(range(S)),
        actions=("up", "down", "left", "right"),
        gamma=gamma,
        terminal=terminal,
        action_mask=~terminal[:, None] & np.ones((S, 4), dtype=bool),
        indptr=indptr,
        next_states=nxt,
        probs=probs,
        rewards=rewards,
        initial=initial,
        name=f"slip-gridworld-{n}x{n}",
        meta={"shape": (n, n)},
    )


def long_chain(
    n_states: int = 1000, success: float = 0.9, gamma: float = 0.99, step_reward: float = -1.0
) -> FiniteMDP:
    """A long chain: the worst case of synchronous value iteration.

    States 0..n-1 in a line and a terminal state n at the right end. ``right`` moves
    one state right with probability ``success`` and stays put otherwise; ``left``
    moves one state left (state 0 stays). Every step earns ``step_reward``; the start
    is state 0. The value of the start depends on states n steps away, so synchronous
    sweeps need at least about n of them; sweeps ordered from the end need a few.
    With gamma = 1, v_*(s) = step_reward * (n - s) / success.

    Args:
        n_states: Non-terminal states, >= 1.
        success: Probability that ``right`` moves, in (0, 1).
        gamma: Discount rate in [0, 1].
        step_reward: Reward of every step.
    """
    n = _check_count("n_states", n_states, 1)
    q = _check_probability("success", success, open_low=True)
    S = n + 1
    idx = np.arange(S)
    target = np.stack([np.maximum(idx - 1, 0), idx + 1], axis=1)
    target[n] = -1
    # "right" slips in place with probability 1 - success; "left" never slips.
    indptr, nxt, probs, rewards = _moves_with_slip(target, np.array([0.0, 1.0 - q]), step_reward)
    terminal = np.zeros(S, dtype=bool)
    terminal[n] = True
    initial = np.zeros(S)
    initial[0] = 1.0
    return FiniteMDP(
        states=tuple(range(S)),
        actions=("left", "right"),
        gamma=gamma,
        terminal=terminal,
        action_mask=~terminal[:, None] & np.ones((S, 2), dtype=bool),
        indptr=indptr,
        next_states=nxt,
        probs=probs,
        rewards=rewards,
        initial=initial,
        name=f"long-chain-{n}",
        meta={"x": list(range(S)), "xlabel": "State"},
    )


def random_mdp(
    n_states: int = 100,
    n_actions: int = 4,
    n_successors: int = 10,
    seed: int | np.random.Generator | None = 0,
    gamma: float = 0.95,
) -> FiniteMDP:
    """A random sparse MDP: every (s, a) leads to ``n_successors`` distinct next states.

    The outcome table is written directly (no dense matrix, no per-state Python loop),
    so 10^6 states x 4 actions x 10 successors (4 * 10^7 outcomes, 0.8 GB) build in
    seconds. For each (s, a): the next states are a sorted random set of distinct
    states, their probabilities are uniform random numbers normalised to sum to 1, and
    each outcome's reward is uniform in [0, 1). Every action is available everywhere;
    there are no terminal states (a continuing task) and the start is uniform.

    Args:
        n_states: S >= 1.
        n_actions: A >= 1.
        n_successors: Next states per (s, a), 1..S.
        seed: Seed or generator (same seed, same MDP).
        gamma: Discount rate.
    """
    S = _check_count("n_states", n_states, 1)
    A = _check_count("n_actions", n_actions, 1)
    K = _check_count("n_successors", n_successors, 1)
    if K > S:
        raise InvalidArgumentError(f"n_successors ({K}) cannot exceed n_states ({S})")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    rows = S * A
    idx_dtype = np.int32 if S < 2**31 else np.int64
    # K distinct sorted states per row: sort K draws from [0, S - K], add 0..K-1.
    nxt = rng.integers(0, S - K + 1, size=(rows, K), dtype=np.int64)
    nxt.sort(axis=1)
    nxt += np.arange(K)
    next_states: np.ndarray[Any, Any] = nxt.astype(idx_dtype).ravel()
    del nxt
    probs = rng.random((rows, K))
    probs += 1e-3  # keep every outcome possible
    probs /= probs.sum(axis=1, keepdims=True)
    rewards = rng.random(rows * K)
    indptr = np.arange(0, rows * K + 1, K, dtype=np.int64)
    return FiniteMDP(
        states=tuple(range(S)),
        actions=tuple(range(A)),
        gamma=gamma,
        terminal=np.zeros(S, dtype=bool),
        action_mask=np.ones((S, A), dtype=bool),
        indptr=indptr,
        next_states=next_states,
        probs=probs.ravel(),
        rewards=rewards,
        initial=np.full(S, 1.0 / S),
        name=f"random-mdp-{S}x{A}x{K}",
    )


register_problem(
    random_mdp,
    "Random sparse MDP (default 100 states, 4 actions, 10 successors, seed 0, gamma 0.95).",
    max_episode_steps=200,
    section="generator",
)
register_problem(
    slip_gridworld,
    "Large slippery gridworld (default 50 x 50, slip 0.1, -1 a step, goal corner, gamma 0.99).",
    max_episode_steps=10_000,
    section="generator",
)
register_problem(
    long_chain,
    "Long chain to a terminal end (default 1000 states, right succeeds 0.9, gamma 0.99).",
    max_episode_steps=100_000,
    section="generator",
)
