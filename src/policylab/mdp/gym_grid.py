"""Grid layouts of Gymnasium's toy-text gridworlds (FrozenLake, CliffWalking).

:meth:`FiniteMDP.from_gymnasium` reads an env's model ``P``; this module reads what
the env itself says about its map (FrozenLake's ``desc``, CliffWalking's ``shape``
and ``_cliff``) so that the MDP carries a :class:`GridLayout` and figures can draw it.
Nothing is inferred from the number of states alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from policylab.mdp.grid import Cell, GridLayout

__all__ = ["gym_action_labels", "gym_grid_layout"]

#: What the actions of Gymnasium's toy-text envs mean, as documented by Gymnasium
#: (by the unwrapped env's class name).
_TOY_TEXT_ACTIONS: dict[str, tuple[str, ...]] = {
    "FrozenLakeEnv": ("left", "down", "right", "up"),
    "CliffWalkingEnv": ("up", "right", "down", "left"),
    "TaxiEnv": ("south", "north", "east", "west", "pickup", "dropoff"),
}

#: FrozenLake's actions 0..3 are left, down, right, up.
_FROZEN_LAKE_MOVES: tuple[Cell, ...] = ((0, -1), (1, 0), (0, 1), (-1, 0))
#: CliffWalking's actions 0..3 are up, right, down, left.
_CLIFF_WALKING_MOVES: tuple[Cell, ...] = ((-1, 0), (0, 1), (1, 0), (0, -1))
_FROZEN_LAKE_KINDS = {"S": "start", "F": "frozen", "H": "hole", "G": "goal"}


def gym_action_labels(base: Any, n_actions: int) -> list[Any]:
    """Action labels of an unwrapped env: Gymnasium's documented names where known.

    FrozenLake's 0..3 are left, down, right, up; CliffWalking's up, right, down, left;
    Taxi's south, north, east, west, pickup, dropoff. Any other env keeps 0..A-1. The
    index order is the env's own either way, so action indices mean the same.
    """
    names = _TOY_TEXT_ACTIONS.get(type(base).__name__)
    if names is not None and len(names) == n_actions:
        return list(names)
    return list(range(n_actions))


def gym_grid_layout(base: Any, n_states: int, n_actions: int) -> GridLayout | None:
    """The grid layout of an unwrapped toy-text env, or None if it is not a known grid.

    State s lies in cell (s // columns, s % columns), the order both envs use.

    Args:
        base: The unwrapped environment.
        n_states: Number of states of its model.
        n_actions: Number of actions of its model.
    """
    desc = getattr(base, "desc", None)
    if desc is not None and n_actions == 4:  # FrozenLake
        rows = [[_char(x) for x in row] for row in np.asarray(desc)]
        n_rows, n_cols = len(rows), len(rows[0]) if rows else 0
        if n_rows * n_cols != n_states or any(
            ch not in _FROZEN_LAKE_KINDS for r in rows for ch in r
        ):
            return None
        kinds = {
            (r, c): _FROZEN_LAKE_KINDS[rows[r][c]] for r in range(n_rows) for c in range(n_cols)
        }
        return _layout(n_rows, n_cols, kinds, _FROZEN_LAKE_MOVES)
    shape = getattr(base, "shape", None)
    cliff = getattr(base, "_cliff", None)
    if shape is not None and cliff is not None and n_actions == 4:  # CliffWalking
        n_rows, n_cols = (int(x) for x in shape)
        cliff_arr = np.asarray(cliff, dtype=bool)
        if n_rows * n_cols != n_states or cliff_arr.shape != (n_rows, n_cols):
            return None
        start = int(getattr(base, "start_state_index", (n_rows - 1) * n_cols))
        kinds = {}
        for r in range(n_rows):
            for c in range(n_cols):
                kinds[(r, c)] = "cliff" if cliff_arr[r, c] else "floor"
        kinds[divmod(start, n_cols)] = "start"
        kinds[(n_rows - 1, n_cols - 1)] = "goal"
        return _layout(n_rows, n_cols, kinds, _CLIFF_WALKING_MOVES)
    return None


def _char(x: Any) -> str:
    return x.decode() if isinstance(x, bytes) else str(x)


def _layout(
    n_rows: int, n_cols: int, kinds: dict[Cell, str], moves: tuple[Cell, ...]
) -> GridLayout:
    cells = tuple((s // n_cols, s % n_cols) for s in range(n_rows * n_cols))
    return GridLayout(shape=(n_rows, n_cols), cells=cells, kinds=kinds, moves=moves)
