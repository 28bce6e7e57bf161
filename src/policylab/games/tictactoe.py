"""Tic-tac-toe on a 3x3 board; cells 1-9 row by row from the top left (actions 0-8).

A position is two 9-bit masks, one per player; X (player 0) moves first.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from policylab.games.base import Game, GameState

__all__ = ["LINES", "TicTacToe", "TicTacToeState"]

LINES: tuple[int, ...] = tuple(
    sum(1 << c for c in cells)
    for cells in (
        (0, 1, 2),
        (3, 4, 5),
        (6, 7, 8),
        (0, 3, 6),
        (1, 4, 7),
        (2, 5, 8),
        (0, 4, 8),
        (2, 4, 6),
    )
)
"""The eight winning lines as 9-bit masks (rows, columns, diagonals)."""

_FULL = (1 << 9) - 1


def _has_line(bits: int) -> bool:
    return any(bits & line == line for line in LINES)


class TicTacToeState(GameState):
    """A tic-tac-toe position: the cells of X and of O as bit masks."""

    __slots__ = ("o", "x")

    def __init__(self, x: int = 0, o: int = 0, moves: tuple[int, ...] = ()) -> None:
        self.x = x
        self.o = o
        self._moves = moves
        self._winner = 0 if _has_line(x) else (1 if _has_line(o) else None)

    @property
    def game(self) -> Game:
        """The game: tic-tac-toe."""
        return TIC_TAC_TOE

    def is_full(self) -> bool:
        """True when all nine cells are taken."""
        return (self.x | self.o) == _FULL

    def legal_actions(self) -> tuple[int, ...]:
        """The empty cells (none once the game is over)."""
        if self._winner is not None:
            return ()
        taken = self.x | self.o
        return tuple(c for c in range(9) if not taken >> c & 1)

    def _apply(self, action: int) -> TicTacToeState:
        bit = 1 << action
        if self.player == 0:
            return TicTacToeState(self.x | bit, self.o, (*self._moves, action))
        return TicTacToeState(self.x, self.o | bit, (*self._moves, action))

    @property
    def key(self) -> tuple[int, int]:
        """(X's cells, O's cells)."""
        return (self.x, self.o)

    def encode(self) -> NDArray[np.float32]:
        """Planes (2, 3, 3): the player to move's marks, then the opponent's."""
        mine, theirs = (self.x, self.o) if self.player == 0 else (self.o, self.x)
        out = np.zeros((2, 9), dtype=np.float32)
        for c in range(9):
            out[0, c] = mine >> c & 1
            out[1, c] = theirs >> c & 1
        return out.reshape(2, 3, 3)

    def cell(self, c: int) -> str:
        """'X', 'O' or '.' for cell c (0-indexed)."""
        return "X" if self.x >> c & 1 else ("O" if self.o >> c & 1 else ".")

    def __str__(self) -> str:
        return "\n".join(" ".join(self.cell(3 * r + k) for k in range(3)) for r in range(3))


class TicTacToe(Game):
    """Tic-tac-toe: X (player 0) and O take turns; three in a row, column or diagonal wins."""

    name = "tic-tac-toe"
    n_actions = 9
    rows = 3
    cols = 3
    player_names = ("X", "O")

    def initial(self) -> TicTacToeState:
        """The empty board, X to move."""
        return TicTacToeState()


TIC_TAC_TOE = TicTacToe()
