"""Grid-shaped problems: how states map to cells, and one builder for gridworld MDPs.

Every gridworld of policylab (the notes' mountain and slippery gridworlds, Sutton &
Barto's gridworlds, cliff walking, the windy gridworld) is built by :func:`grid_mdp`,
so moves, walls, slips and rewards are written once. Figures read the
:class:`GridLayout` an MDP carries and never guess a layout.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from policylab.exceptions import InvalidMDPError

if TYPE_CHECKING:
    from policylab.mdp.finite import FiniteMDP

__all__ = ["MOVES", "Cell", "GridLayout", "grid_mdp"]

Cell = tuple[int, int]
"""A cell as (row, column), row 0 at the top."""

#: The four compass moves as (d_row, d_col), in the order of the actions.
MOVES: dict[str, Cell] = {"up": (-1, 0), "down": (1, 0), "left": (0, -1), "right": (0, 1)}


@dataclass(frozen=True)
class GridLayout:
    """The map from an MDP's states to the cells of a rectangular grid.

    Attributes:
        shape: (rows, columns).
        cells: The cell of each state index, in state order.
        kinds: The kind of each cell by its map character's meaning ("grass",
            "mountain", "goal", "start", "wall", "cliff", ...). Cells absent from
            ``cells`` but present here (walls) are not states.
        thin_walls: Pairs of adjacent cells with a wall between them.
        moves: The (d_row, d_col) of each action, in action order (for arrows).
        wind: The upward push of each column (the windy gridworld), or None.
    """

    shape: tuple[int, int]
    cells: tuple[Cell, ...]
    kinds: Mapping[Cell, str] = field(default_factory=dict)
    thin_walls: frozenset[frozenset[Cell]] = frozenset()
    moves: tuple[Cell, ...] = tuple(MOVES.values())
    wind: tuple[int, ...] | None = None

    def state_at(self, cell: Cell) -> int | None:
        """The state index in a cell, or None if the cell holds no state."""
        try:
            return self.cells.index(cell)
        except ValueError:
            return None

    def to_array(self, values: Sequence[float] | np.ndarray, fill: float = np.nan) -> np.ndarray:
        """Lay per-state values out on the grid (cells without a state get ``fill``)."""
        out = np.full(self.shape, fill, dtype=np.float64)
        vals = np.asarray(values, dtype=np.float64)
        for s, (r, c) in enumerate(self.cells):
            out[r, c] = vals[s]
        return out


def grid_mdp(
    rows: Sequence[str],
    legend: Mapping[str, str],
    reward: Callable[[Cell, Cell, str], float],
    *,
    terminal_kinds: Iterable[str] = ("goal",),
    start_kinds: Iterable[str] = ("start",),
    slip: Callable[[int], Sequence[tuple[float, int]]] | None = None,
    thin_walls: Iterable[tuple[Cell, Cell]] = (),
    jumps: Mapping[Cell, tuple[Cell, float]] | None = None,
    wind: Sequence[int] | None = None,
    moves: Mapping[str, Cell] | None = None,
    labels: Callable[[Cell], Hashable] | None = None,
    respawn: Mapping[str, Cell] | None = None,
    gamma: float = 1.0,
    name: str = "gridworld",
) -> FiniteMDP:
    """Build a gridworld MDP from a character map.

    Each character of ``rows`` is a cell; ``legend`` gives its kind. Cells of kind
    ``"wall"`` are blocked and hold no state. A move off the grid, into a blocked cell or
    across a thin wall leaves the agent where it is. Rewards are ``reward(from, to,
    kind_of_to)`` where ``to`` is the cell the agent ends up in (``to == from`` on a
    bump).

    Args:
        rows: The map, one string per row (all the same length).
        legend: Character -> kind, e.g. ``{".": "grass", "M": "mountain", "G": "goal"}``.
        reward: The reward of a transition, by cells and the kind of the destination.
        terminal_kinds: Kinds whose cells are terminal states.
        start_kinds: Kinds whose cells share the start distribution (default: all
            non-terminal cells if the map has no such cell).
        slip: ``slip(a)`` gives [(probability, actual action index)] for the intended
            action ``a``; default: moves are deterministic.
        thin_walls: Pairs of adjacent cells with a wall between them.
        jumps: From a cell, every action moves to a fixed cell with a fixed reward
            (Sutton & Barto's Example 3.5 A -> A'), ignoring ``reward``.
        wind: Upward push per column, added to every move (windy gridworld).
        moves: Action label -> (d_row, d_col); default the four compass moves.
        labels: Cell -> state label; default the cell tuple itself.
        respawn: Kind -> cell: entering a cell of that kind sends the agent to the given
            cell instead (cliff walking), still rewarded by ``reward`` with the entered
            cell's kind.
        gamma: Discount rate.
        name: The MDP's name.

    Returns:
        The MDP, with its :class:`GridLayout` in ``mdp.grid``.
    """
    from policylab.mdp.finite import FiniteMDP

    if isinstance(rows, str) or not all(isinstance(r, str) for r in rows):
        raise InvalidMDPError(f"grid rows must be a list of strings, one per row; got {rows!r:.80}")
    if not callable(reward):
        raise InvalidMDPError(
            f"reward must be a function reward(from_cell, to_cell, kind); got {reward!r:.60}"
        )
    if wind is not None and not all(
        isinstance(w, int | np.integer) and not isinstance(w, bool) for w in wind
    ):
        raise InvalidMDPError(f"wind must hold integers (cells pushed up); got {list(wind)!r}")
    if not rows or any(len(r) != len(rows[0]) for r in rows):
        raise InvalidMDPError(
            f"grid rows must be non-empty and of equal length; got {list(rows)!r}"
        )
    n_rows, n_cols = len(rows), len(rows[0])
    if wind is not None and len(wind) != n_cols:
        raise InvalidMDPError(
            f"wind must give one upward push per column: {n_cols} columns, "
            f"{len(wind)} values given ({list(wind)!r})"
        )
    kinds: dict[Cell, str] = {}
    for r, line in enumerate(rows):
        for c, ch in enumerate(line):
            if ch not in legend:
                raise InvalidMDPError(
                    f"grid character {ch!r} at {(r, c)} is not in the legend {dict(legend)}"
                )
            kinds[(r, c)] = legend[ch]
    cells = [cell for cell, k in kinds.items() if k != "wall"]
    mv = dict(moves) if moves is not None else dict(MOVES)
    move_list = list(mv.values())
    walls = frozenset(frozenset(w) for w in thin_walls)
    term_kinds = set(terminal_kinds)
    label = labels or (lambda cell: cell)
    lab = {cell: label(cell) for cell in cells}
    jumps = jumps or {}
    respawn = respawn or {}

    def land(cell: Cell, d: Cell) -> Cell:
        r, c = cell
        dr, dc = d
        if wind is not None:
            dr -= wind[c]
        target = (min(max(r + dr, 0), n_rows - 1), min(max(c + dc, 0), n_cols - 1))
        if kinds[target] == "wall":
            return cell
        if abs(dr) + abs(dc) == 1 and frozenset((cell, target)) in walls:
            return cell
        return target

    dynamics: dict[Hashable, dict[Hashable, list[tuple[float, Hashable, float]]]] = {}
    terminal = [lab[cell] for cell in cells if kinds[cell] in term_kinds]
    for cell in cells:
        if kinds[cell] in term_kinds:
            dynamics[lab[cell]] = {}
            continue
        acts: dict[Hashable, list[tuple[float, Hashable, float]]] = {}
        for a, a_lab in enumerate(mv):
            if cell in jumps:
                dest, rew = jumps[cell]
                acts[a_lab] = [(1.0, lab[dest], float(rew))]
                continue
            outs = []
            for pr, actual in slip(a) if slip is not None else [(1.0, a)]:
                to = land(cell, move_list[actual])
                got = reward(cell, to, kinds[to])
                try:
                    rew = float(got)
                except (TypeError, ValueError):
                    raise InvalidMDPError(
                        f"reward({cell}, {to}, {kinds[to]!r}) returned {got!r}; it must return "
                        "a number"
                    ) from None
                dest = respawn.get(kinds[to], to)
                outs.append((float(pr), lab[dest], rew))
            acts[a_lab] = outs
        dynamics[lab[cell]] = acts
    starts = [lab[c] for c in cells if kinds[c] in set(start_kinds)]
    initial: Any = {s: 1.0 / len(starts) for s in starts} if starts else None
    layout = GridLayout(
        shape=(n_rows, n_cols),
        cells=tuple(cells),
        kinds=kinds,
        thin_walls=walls,
        moves=tuple(move_list),
        wind=None if wind is None else tuple(int(w) for w in wind),
    )
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=gamma,
        terminal=terminal,
        actions=list(mv),
        initial=initial,
        name=name,
        grid=layout,
    )
