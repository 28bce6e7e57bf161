"""The lecture notes' own examples: the recycling robot and the two gridworlds."""

from __future__ import annotations

from policylab.mdp.finite import FiniteMDP
from policylab.mdp.grid import Cell, grid_mdp
from policylab.mdp.policy import Policy
from policylab.problems.registry import register_problem

__all__ = [
    "MOUNTAIN_GRID",
    "SLIPPERY_GRID",
    "mountain_gridworld",
    "mountain_gridworld_bad_policy",
    "recycling_robot",
    "recycling_robot_deterministic_policy",
    "recycling_robot_stochastic_policy",
    "slippery_gridworld",
]


def recycling_robot(
    alpha: float = 0.7,
    beta: float = 0.2,
    r_search: float = 4.0,
    r_wait: float = 1.0,
    r_rescue: float = -3.0,
    gamma: float = 0.9,
) -> FiniteMDP:
    """The recycling robot of notes section 4.3 (Sutton & Barto, Example 3.3).

    States ``high`` and ``low`` (battery level); actions ``search``, ``wait`` and
    ``recharge`` with A(high) = {search, wait}. Searching from high keeps the battery
    high with probability alpha; searching from low keeps it low with probability beta,
    else the battery runs flat, the robot is rescued (reward ``r_rescue``) and recharged
    to high. Waiting keeps the level and earns ``r_wait``; recharging from low goes to
    high with reward 0. A continuing task: the robot starts with a high battery.

    Args:
        alpha: P(high | high, search).
        beta: P(low | low, search).
        r_search: Expected cans while searching.
        r_wait: Expected cans while waiting.
        r_rescue: Reward when rescued after running flat.
        gamma: Discount rate (the notes leave it open; 0.9 by default).
    """
    return FiniteMDP.from_dynamics(
        {
            "high": {
                "search": [(alpha, "high", r_search), (1 - alpha, "low", r_search)],
                "wait": [(1.0, "high", r_wait)],
            },
            "low": {
                "search": [(beta, "low", r_search), (1 - beta, "high", r_rescue)],
                "wait": [(1.0, "low", r_wait)],
                "recharge": [(1.0, "high", 0.0)],
            },
        },
        gamma=gamma,
        actions=["search", "wait", "recharge"],
        initial="high",
        name="recycling-robot",
    )


def recycling_robot_deterministic_policy(mdp: FiniteMDP) -> Policy:
    """The notes' deterministic policy: pi(low) = recharge, pi(high) = search."""
    return Policy.deterministic(mdp, {"low": "recharge", "high": "search"})


def recycling_robot_stochastic_policy(mdp: FiniteMDP) -> Policy:
    """The notes' stochastic policy: in low recharge 0.5, wait 0.4, search 0.1.

    The notes give only the low row; in high this policy searches, as the deterministic
    one does, so that the two differ only where the notes make them differ.
    """
    return Policy.stochastic(
        mdp,
        {"low": {"recharge": 0.5, "wait": 0.4, "search": 0.1}, "high": {"search": 1.0}},
    )


#: The mountain gridworld's map: ``S`` start (grass), ``.`` grass, ``M`` mountain, ``G`` goal.
MOUNTAIN_GRID = (
    ".M.",
    ".MM",
    "S.G",
)

_MOUNTAIN_LEGEND = {".": "grass", "S": "start", "M": "mountain", "G": "goal"}


def _mountain_reward(_from: Cell, _to: Cell, kind: str) -> float:
    if kind == "goal":
        return 5.0
    if kind == "mountain":
        return -3.0
    return -1.0


def mountain_gridworld(gamma: float = 1.0) -> FiniteMDP:
    """The notes' section 5 gridworld with grass, mountains and a goal.

    A 3 x 3 grid (row 0 at the top; the layout is ours, the notes' figure is not
    reproduced in the text)::

        .  M  .
        .  M  M
        S  .  G

    Actions up/down/left/right move deterministically; a move off the grid stays put.
    The reward is that of the cell the agent ends up in: +5 on the terminal transition
    into the goal G, -3 into (or staying on) a mountain M, -1 otherwise (grass). The
    episode starts in S, gamma = 1. On this layout the notes' bad policy
    (:func:`mountain_gridworld_bad_policy`) has value -6 at the start and -5 in the cell
    to its right, as the notes say; the optimal value of the start is 4.
    """
    return grid_mdp(
        MOUNTAIN_GRID, _MOUNTAIN_LEGEND, _mountain_reward, gamma=gamma, name="mountain-gridworld"
    )


def mountain_gridworld_bad_policy(mdp: FiniteMDP) -> Policy:
    """The notes' "bad policy" (Figure 4): a detour over the mountains to the goal.

    From the start: right, then up over both mountains, right, and down over the third
    mountain into the goal. Values: -6 at the start, -5 to its right.
    """
    return Policy.deterministic(
        mdp,
        {
            (2, 0): "right",
            (2, 1): "up",
            (1, 1): "up",
            (0, 1): "right",
            (0, 2): "down",
            (1, 2): "down",
            (0, 0): "right",
            (1, 0): "down",
        },
    )


#: Cell numbers of the slippery gridworld, laid out on the 2 x 2 grid.
SLIPPERY_GRID = ((1, 4), (2, 3))


def slippery_gridworld(
    p_intended: float = 0.7,
    step_reward: float = -1.0,
    goal_reward: float = 10.0,
    gamma: float = 1.0,
) -> FiniteMDP:
    """The notes' section 6 gridworld: four cells, a wall, and slippery moves.

    The states are the cells 1..4 (labels are the integers 1, 2, 3, 4)::

        1 | 4        a wall between 1 (start) and 4 (goal, terminal)
        2   3

    The chosen direction happens with probability ``p_intended`` (0.7) and each of the
    three others with (1 - p_intended) / 3 (0.1); a move into the wall or off the grid
    stays put. Every step earns -1, except entering 4, which earns +10. gamma = 1. The
    notes' sample episode (1 -up-> slips to 2, 2 -right-> 3, 3 -up-> 4 with +10) runs on
    this layout.
    """
    other = (1.0 - p_intended) / 3.0

    def slip(a: int) -> list[tuple[float, int]]:
        probs = [p_intended if b == a else other for b in range(4)]
        return [(pr, b) for b, pr in enumerate(probs) if pr > 0]

    def reward(_from: Cell, _to: Cell, kind: str) -> float:
        return goal_reward if kind == "goal" else step_reward

    return grid_mdp(
        ("SG", ".."),
        {"S": "start", "G": "goal", ".": "floor"},
        reward,
        slip=slip,
        thin_walls=[((0, 0), (0, 1))],
        labels=lambda cell: SLIPPERY_GRID[cell[0]][cell[1]],
        gamma=gamma,
        name="slippery-gridworld",
    )


register_problem(
    recycling_robot,
    "Recycling robot (notes 4.3, S&B Ex. 3.3): battery high/low; search, wait or recharge.",
    policies={
        "deterministic": recycling_robot_deterministic_policy,
        "stochastic": recycling_robot_stochastic_policy,
    },
    max_episode_steps=1000,
    section="notes 4.3",
)
register_problem(
    mountain_gridworld,
    "Notes' section 5 gridworld: 3x3 grass and mountains, -1 grass, -3 mountain, +5 goal.",
    policies={"bad": mountain_gridworld_bad_policy},
    max_episode_steps=200,
    section="notes 5",
)
register_problem(
    slippery_gridworld,
    "Notes' section 6 slippery 2x2 gridworld: wall between cells 1 and 4, moves slip 30%.",
    max_episode_steps=200,
    section="notes 6",
)
