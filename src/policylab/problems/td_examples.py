"""Sutton & Barto's chapter 6 examples, each with the exact answer learners are held to.

The random walk (Example 6.2), the windy gridworld (6.5), cliff walking (6.6) and the
maximisation-bias MDP (6.7).
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.mdp.grid import Cell, grid_mdp
from policylab.problems.registry import register_problem

__all__ = [
    "CLIFF_GRID",
    "WINDY_GRID",
    "WINDY_WIND",
    "cliff_walking",
    "maximization_bias",
    "random_walk",
    "random_walk_true_values",
    "windy_gridworld",
]


def random_walk(n_states: int = 5, left_reward: float = 0.0, gamma: float = 1.0) -> FiniteMDP:
    """The random walk of Example 6.2 (a Markov reward process).

    Non-terminal states ``A, B, C, D, E`` (for ``n_states = 5``; ``1 .. n`` otherwise)
    lie in a row between two terminal states ``left`` and ``right``. Every episode
    starts in the centre state; the one action ``walk`` moves left or right with
    probability 1/2 each. Entering ``right`` earns +1, entering ``left`` earns
    ``left_reward`` (0 in Example 6.2, -1 in the 19-state walk of Figure 7.2); every
    other step earns 0. With gamma = 1 the true values of Example 6.2 are
    1/6, 2/6, ..., 5/6 (see :func:`random_walk_true_values`).

    ``mdp.meta`` holds ``x`` (the position 1..n of each state, NaN on the terminals)
    and ``xlabel`` for the figure of estimated values against state.

    Args:
        n_states: Number of non-terminal states (odd, >= 1, so that there is a centre).
        left_reward: Reward on entering the left terminal state.
        gamma: Discount rate.
    """
    if not isinstance(n_states, int | np.integer) or n_states < 1 or n_states % 2 == 0:
        raise InvalidArgumentError(f"n_states must be an odd positive integer; got {n_states!r}")
    n = int(n_states)
    names = [chr(ord("A") + i) for i in range(n)] if n <= 26 else [str(i + 1) for i in range(n)]
    chain = ["left", *names, "right"]
    dynamics: dict[Hashable, dict[Hashable, list[tuple[float, Hashable, float]]]] = {}
    for i in range(1, n + 1):
        lo, hi = chain[i - 1], chain[i + 1]
        r_lo = float(left_reward) if lo == "left" else 0.0
        r_hi = 1.0 if hi == "right" else 0.0
        dynamics[chain[i]] = {"walk": [(0.5, lo, r_lo), (0.5, hi, r_hi)]}
    dynamics = {"left": {}, **dynamics, "right": {}}
    x = [float("nan"), *[float(i) for i in range(1, n + 1)], float("nan")]
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=gamma,
        terminal=("left", "right"),
        actions=["walk"],
        initial=names[n // 2],
        name="random-walk",
        meta={"x": x, "xlabel": "state", "xticklabels": names},
    )


def random_walk_true_values(n_states: int = 5, left_reward: float = 0.0) -> np.ndarray:
    """The true values of the undiscounted random walk, in the MDP's state order.

    v(i) = left_reward + (1 - left_reward) * i / (n + 1) for the i-th non-terminal state
    (gambler's ruin), 0 on the two terminals: 1/6 .. 5/6 for Example 6.2.
    """
    n = int(n_states)
    i = np.arange(1, n + 1, dtype=np.float64)
    inner = left_reward * (1.0 - i / (n + 1)) + 1.0 * i / (n + 1)
    return np.concatenate([[0.0], inner, [0.0]])


#: Cliff walking's map (Example 6.6): ``S`` start, ``C`` cliff, ``G`` goal, 4 x 12.
CLIFF_GRID = (
    "............",
    "............",
    "............",
    "SCCCCCCCCCCG",
)

#: Actions in Gymnasium's CliffWalking order (0 up, 1 right, 2 down, 3 left).
_GYM_MOVES: dict[str, Cell] = {"up": (-1, 0), "right": (0, 1), "down": (1, 0), "left": (0, -1)}


def cliff_walking(gamma: float = 1.0) -> FiniteMDP:
    """Cliff walking (Example 6.6): a 4 x 12 grid with a cliff along the bottom edge.

    Every step earns -1; stepping into the cliff earns -100 and sends the agent back to
    the start ``S`` (bottom left); the episode ends on entering the goal ``G`` (bottom
    right). The optimal path runs along the cliff edge: 13 steps, return -13. States
    are the cells (row, col) in row-major order and actions are ordered up, right,
    down, left, so state and action indices equal Gymnasium's ``CliffWalking-v1``
    (``FiniteMDP.from_gymnasium("CliffWalking-v1")`` gives the same dynamics).

    Args:
        gamma: Discount rate (1 in the book).
    """

    def reward(_from: Cell, _to: Cell, kind: str) -> float:
        return -100.0 if kind == "cliff" else -1.0

    return grid_mdp(
        CLIFF_GRID,
        {".": "floor", "S": "start", "C": "cliff", "G": "goal"},
        reward,
        moves=_GYM_MOVES,
        respawn={"cliff": (3, 0)},
        gamma=gamma,
        name="cliff-walking",
    )


#: The windy gridworld's map (Example 6.5), 7 x 10: ``S`` start, ``G`` goal.
WINDY_GRID = (
    "..........",
    "..........",
    "..........",
    "S......G..",
    "..........",
    "..........",
    "..........",
)

#: Upward wind strength of each column of the windy gridworld.
WINDY_WIND = (0, 0, 0, 1, 1, 1, 2, 2, 1, 0)

_KING_MOVES: dict[str, Cell] = {
    "up": (-1, 0),
    "down": (1, 0),
    "left": (0, -1),
    "right": (0, 1),
    "up-left": (-1, -1),
    "up-right": (-1, 1),
    "down-left": (1, -1),
    "down-right": (1, 1),
}


def windy_gridworld(king_moves: bool = False, gamma: float = 1.0) -> FiniteMDP:
    """The windy gridworld (Example 6.5): a crosswind pushes the agent upward.

    A 7 x 10 grid; the wind of the column the agent starts a move in (0 0 0 1 1 1 2 2
    1 0) shifts the result of every move upward by that many cells, and the agent stays
    inside the grid. Every step earns -1 until the goal ``G`` is reached, so the return
    is minus the episode length. The shortest path takes 15 steps (v*(S) = -15), or 7
    with ``king_moves`` (Exercise 6.9, eight moves).

    Args:
        king_moves: Also allow the four diagonal moves.
        gamma: Discount rate (1 in the book).
    """
    return grid_mdp(
        WINDY_GRID,
        {".": "floor", "S": "start", "G": "goal"},
        lambda _f, _t, _k: -1.0,
        wind=WINDY_WIND,
        moves=_KING_MOVES if king_moves else None,
        gamma=gamma,
        name="windy-gridworld",
    )


def maximization_bias(
    n_actions_b: int = 10,
    mean: float = -0.1,
    std: float = 1.0,
    n_points: int = 8,
    gamma: float = 1.0,
) -> FiniteMDP:
    """The small MDP of Example 6.7 that shows maximisation bias (Figure 6.5).

    The episode starts in ``A``. There ``right`` ends the episode with reward 0, and
    ``left`` moves to ``B`` with reward 0. From ``B`` each of ``n_actions_b`` actions
    (``b1`` ... ) ends the episode with a reward drawn from a normal distribution with
    mean -0.1 and variance 1, so going left is worse in expectation (q*(A, left) =
    -0.1 < 0 = q*(A, right)), yet the maximum of the noisy estimates in B looks positive.

    The finite MDP stores reward distributions with finitely many values, so the normal
    is replaced by its ``n_points``-point Gauss-Hermite quadrature: a discrete
    distribution with the same mean, variance and moments up to order ``2 n_points -
    1``.

    Args:
        n_actions_b: Number of actions in ``B``.
        mean: Mean reward of the actions in ``B``.
        std: Standard deviation of those rewards.
        n_points: Support size of the discretised normal (>= 2).
        gamma: Discount rate.
    """
    if int(n_actions_b) < 1:
        raise InvalidArgumentError(f"n_actions_b must be >= 1; got {n_actions_b!r}")
    if int(n_points) < 2:
        raise InvalidArgumentError(f"n_points must be >= 2; got {n_points!r}")
    if not std > 0:
        raise InvalidArgumentError(f"std must be positive; got {std!r}")
    nodes, weights = np.polynomial.hermite_e.hermegauss(int(n_points))
    weights = weights / weights.sum()
    rewards = mean + std * nodes
    b_actions = [f"b{i + 1}" for i in range(int(n_actions_b))]
    outcomes = [(float(w), "end", float(r)) for w, r in zip(weights, rewards, strict=True)]
    dynamics: dict[Hashable, dict[Hashable, list[tuple[float, Hashable, float]]]] = {
        "A": {"right": [(1.0, "end", 0.0)], "left": [(1.0, "B", 0.0)]},
        "B": {a: list(outcomes) for a in b_actions},
        "end": {},
    }
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=gamma,
        terminal=("end",),
        actions=["right", "left", *b_actions],
        initial="A",
        name="maximization-bias",
    )


register_problem(
    random_walk,
    "Random walk (S&B Ex. 6.2): 5 states A..E between two ends; +1 on the right; v = 1/6..5/6.",
    max_episode_steps=1000,
    section="S&B Example 6.2",
)
register_problem(
    cliff_walking,
    "Cliff walking (S&B Ex. 6.6): 4x12, -1 a step, -100 and back to start off the cliff.",
    max_episode_steps=1000,
    section="S&B Example 6.6",
)
register_problem(
    windy_gridworld,
    "Windy gridworld (S&B Ex. 6.5): 7x10, upward wind 0-2 by column, -1 a step; 15 steps best.",
    max_episode_steps=1000,
    section="S&B Example 6.5",
)
register_problem(
    maximization_bias,
    "Maximisation bias MDP (S&B Ex. 6.7): A -left-> B -> N(-0.1, 1) rewards, or A -right-> end.",
    max_episode_steps=10,
    section="S&B Example 6.7",
)
