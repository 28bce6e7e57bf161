"""Small random MDPs and a brute-force oracle shared by the planning tests."""

from __future__ import annotations

import itertools

import numpy as np

import policylab as pl


def small_random_mdp(
    seed: int, n_states: int, n_actions: int, gamma: float, episodic: bool = False
) -> pl.FiniteMDP:
    """A dense random MDP; episodic ones add a terminal state reached w.p. >= 0.1 per step.

    Some actions are made unavailable at random (never all of a state's).
    """
    rng = np.random.default_rng(seed)
    S = n_states + (1 if episodic else 0)
    P = rng.random((n_actions, S, S)) ** 3
    if episodic:
        P[:, :, -1] = 0.0
        P /= P.sum(axis=2, keepdims=True)
        P *= 0.9
        P[:, :, -1] += 0.1
    P /= P.sum(axis=2, keepdims=True)
    R = rng.normal(size=(S, n_actions))
    mask = rng.random((S, n_actions)) < 0.8
    mask[np.arange(S), rng.integers(0, n_actions, S)] = True
    return pl.FiniteMDP.from_arrays(
        P, R, gamma=gamma, terminal=[S - 1] if episodic else None, action_mask=mask
    )


def dense_policy_value(mdp: pl.FiniteMDP, probs: np.ndarray, gamma: float) -> np.ndarray:
    """Oracle: v_pi by a dense linear solve on the non-terminal states."""
    S, A = mdp.n_states, mdp.n_actions
    T = mdp.transition_matrix.toarray().reshape(S, A, S)
    P = np.einsum("sa,sat->st", probs, T)
    r = np.einsum("sa,sa->s", probs, mdp.expected_reward)
    live = ~mdp.terminal
    v = np.zeros(S)
    v[live] = np.linalg.solve(np.eye(live.sum()) - gamma * P[np.ix_(live, live)], r[live])
    return v


def brute_force_optimum(mdp: pl.FiniteMDP, gamma: float) -> np.ndarray:
    """Oracle: v_* as the state-wise maximum over every deterministic policy."""
    S, A = mdp.n_states, mdp.n_actions
    choices = [np.flatnonzero(mdp.action_mask[s]) if not mdp.terminal[s] else [0] for s in range(S)]
    best = np.full(S, -np.inf)
    for acts in itertools.product(*choices):
        probs = np.zeros((S, A))
        probs[np.arange(S), list(acts)] = 1.0
        probs[mdp.terminal] = 0.0
        best = np.maximum(best, dense_policy_value(mdp, probs, gamma))
    return best
