"""Random MDPs built directly in sparse form, for tests and benchmarks at any scale."""

from __future__ import annotations

from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.problems.registry import register_problem

__all__ = ["random_mdp"]


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
    for name, x in (
        ("n_states", n_states),
        ("n_actions", n_actions),
        ("n_successors", n_successors),
    ):
        if isinstance(x, bool) or not isinstance(x, (int, np.integer)) or x < 1:
            raise InvalidArgumentError(f"{name} must be an integer >= 1; got {x!r}")
    S, A, K = int(n_states), int(n_actions), int(n_successors)
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
