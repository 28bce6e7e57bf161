"""Small exact solvers and synthetic problems for the figure tests.

The figures are tested on every built-in problem they fit and on synthetic problems
shaped like those of other layers (the gambler, car rental, Blackjack), built here
from their definitions so these tests need nothing but the core.
"""

from __future__ import annotations

import numpy as np

import policylab as pl
from policylab.mdp.grid import GridLayout


def dense(mdp: pl.FiniteMDP) -> np.ndarray:
    S, A = mdp.n_states, mdp.n_actions
    return mdp.transition_matrix.toarray().reshape(S, A, S)


def evaluate(mdp: pl.FiniteMDP, pi: pl.Policy) -> np.ndarray:
    """v_pi by the linear solve (I - gamma P_pi) v = r_pi over the non-terminal states."""
    P = dense(mdp)
    P_pi = np.einsum("sa,sat->st", pi.probs, P)
    r_pi = (pi.probs * mdp.expected_reward).sum(axis=1)
    live = ~mdp.terminal
    v = np.zeros(mdp.n_states)
    M = np.eye(mdp.n_states) - mdp.gamma * P_pi
    v[live] = np.linalg.solve(M[np.ix_(live, live)], r_pi[live])
    return v


def action_values(mdp: pl.FiniteMDP, v: np.ndarray) -> np.ndarray:
    """q(s, a) = r(s, a) + gamma sum_s' p(s'|s, a) v(s'), -inf-free (0 where unavailable)."""
    q = mdp.expected_reward + mdp.gamma * dense(mdp) @ v
    return np.where(mdp.action_mask, q, 0.0)


def optimal(mdp: pl.FiniteMDP, iters: int = 10_000, tol: float = 1e-10):
    """Value iteration: (v*, q*, greedy policy)."""
    P = dense(mdp)
    v = np.zeros(mdp.n_states)
    for _ in range(iters):
        q = mdp.expected_reward + mdp.gamma * P @ v
        q = np.where(mdp.action_mask, q, -np.inf)
        new = np.where(mdp.terminal, 0.0, q.max(axis=1, initial=-np.inf))
        new = np.where(np.isfinite(new), new, 0.0)
        if np.max(np.abs(new - v)) < tol:
            v = new
            break
        v = new
    q = np.where(mdp.action_mask, mdp.expected_reward + mdp.gamma * P @ v, -np.inf)
    idx = np.where(mdp.terminal, 0, q.argmax(axis=1))
    return v, np.where(mdp.action_mask, q, 0.0), pl.Policy.from_actions(mdp, idx)


def gambler(goal: int = 100, p_heads: float = 0.4) -> pl.FiniteMDP:
    """Sutton & Barto's gambler (Example 4.3): capital 0..goal, stakes as numeric actions."""
    dyn: dict = {}
    for s in range(1, goal):
        dyn[s] = {
            a: [(p_heads, s + a, 1.0 if s + a == goal else 0.0), (1 - p_heads, s - a, 0.0)]
            for a in range(1, min(s, goal - s) + 1)
        }
    dyn[0], dyn[goal] = {}, {}
    order = {s: dyn[s] for s in range(goal + 1)}
    return pl.FiniteMDP.from_dynamics(
        order,
        gamma=1.0,
        terminal=[0, goal],
        actions=list(range(1, goal // 2 + 1)),
        name="gambler",
        meta={"x": list(range(goal + 1)), "xlabel": "capital", "action_label": "stake"},
    )


def random_walk(n: int = 5) -> pl.FiniteMDP:
    """The 5-state random walk (Example 6.2) with one action: +1 on the right exit."""
    states = ["L"] + [chr(ord("A") + i) for i in range(n)] + ["R"]
    dyn: dict = {"L": {}, "R": {}}
    for i in range(1, n + 1):
        left, right = states[i - 1], states[i + 1]
        dyn[states[i]] = {"walk": [(0.5, left, 0.0), (0.5, right, 1.0 if right == "R" else 0.0)]}
    return pl.FiniteMDP.from_dynamics(
        {s: dyn[s] for s in states},
        gamma=1.0,
        terminal=["L", "R"],
        initial="C",
        name="random-walk",
        meta={"x": list(range(n + 2)), "xlabel": "state (A..E)"},
    )


def car_rental(n: int = 6, max_move: int = 2) -> pl.FiniteMDP:
    """A small car rental: cars (first, second); move up to max_move overnight, then rent."""
    dyn: dict = {}
    for i in range(n):
        for j in range(n):
            acts = {}
            for a in range(-max_move, max_move + 1):
                if not (0 <= i - a < n and 0 <= j + a < n):
                    continue
                i2, j2 = i - a, j + a
                outs = []
                for di, dj, p in ((0, 0, 0.4), (-1, 0, 0.3), (0, -1, 0.3)):
                    rent = (di < 0 and i2 > 0) + (dj < 0 and j2 > 0)
                    outs.append((p, (max(i2 + di, 0), max(j2 + dj, 0)), 10.0 * rent - 2.0 * abs(a)))
                acts[a] = outs
            dyn[(i, j)] = acts
    cells = tuple((i, j) for i in range(n) for j in range(n))
    layout = GridLayout(shape=(n, n), cells=cells, moves=())
    return pl.FiniteMDP.from_dynamics(
        dyn,
        gamma=0.9,
        actions=list(range(-max_move, max_move + 1)),
        grid=layout,
        name="car-rental",
        meta={
            "axis_labels": ("cars at the first location", "cars at the second location"),
            "action_label": "cars moved from first to second",
        },
    )


def blackjack_like() -> pl.FiniteMDP:
    """A Blackjack-shaped MDP: states (player_sum, dealer_card, usable_ace), stick or hit.

    Not the real game: sticking ends the episode with a reward that grows with the
    sum against the dealer's card; hitting adds 1..3 to the sum, busting over 21.
    """
    dyn: dict = {}
    for p in range(12, 22):
        for d in range(1, 11):
            for ace in (True, False):
                win = (p - 12) / 9 - (d - 1) / 18
                stick = [(1.0, "end", float(np.clip(win, -1, 1)))]
                hit = []
                for k in (1, 2, 3):
                    q = p + k
                    if q > 21:
                        hit.append((1 / 3, "end", -1.0))
                    else:
                        hit.append((1 / 3, (q, d, ace), 0.0))
                merged: dict = {}
                for pr, nxt, r in hit:
                    merged[(nxt, r)] = merged.get((nxt, r), 0.0) + pr
                dyn[(p, d, ace)] = {
                    "stick": stick,
                    "hit": [(pr, n, r) for (n, r), pr in merged.items()],
                }
    dyn["end"] = {}
    return pl.FiniteMDP.from_dynamics(
        dyn,
        gamma=1.0,
        terminal=["end"],
        actions=["stick", "hit"],
        name="blackjack-like",
        meta={"blackjack": True},
    )


class FakeResult:
    """A learner result shaped like the tabular layer's: returns and an error curve."""

    def __init__(self, seed: int, episodes: int = 200, points: int = 20) -> None:
        rng = np.random.default_rng(seed)
        self.episode_returns = -50 * np.exp(-np.arange(episodes) / 40) + rng.normal(0, 3, episodes)
        self.checkpoints = np.linspace(episodes / points, episodes, points)
        self.error_rms = np.exp(-self.checkpoints / 60) + rng.normal(0, 0.02, points) ** 2
        self.algorithm = "fake"
