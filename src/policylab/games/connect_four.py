"""Connect Four on 6 rows x 7 columns, as bitboards (columns 1-7; actions 0-6).

A position is two 64-bit masks in the layout of Pascal Pons' solver: column c holds
bits 7c .. 7c+5 from the bottom up, bit 7c+6 stays empty as a sentinel, so that
four in a line is found with four shifts and ands. ``current`` holds the stones of
the player to move and ``mask`` every stone. The hot loops (solver, rollouts) are
compiled with numba in :mod:`policylab.games._c4`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from policylab.games.base import Game, GameState

__all__ = ["COLS", "ROWS", "ConnectFour", "ConnectFourState"]

ROWS = 6
COLS = 7
_H1 = ROWS + 1
_BOTTOM = sum(1 << (c * _H1) for c in range(COLS))
_BOARD = _BOTTOM * ((1 << ROWS) - 1)
_CELL_BITS = np.array(
    [[c * _H1 + ROWS - 1 - r for c in range(COLS)] for r in range(ROWS)], dtype=np.uint64
)
"""The bit of each cell, rows from the top down (the layout of :meth:`encode`)."""


def has_four(bits: int) -> bool:
    """True if ``bits`` (one player's stones) hold four in a line in any direction."""
    for shift in (1, _H1, _H1 - 1, _H1 + 1):  # vertical, horizontal, both diagonals
        m = bits & (bits >> shift)
        if m & (m >> (2 * shift)):
            return True
    return False


class ConnectFourState(GameState):
    """A Connect Four position as (``current``, ``mask``) bitboards plus its move list."""

    __slots__ = ("current", "mask")

    def __init__(
        self,
        current: int = 0,
        mask: int = 0,
        moves: tuple[int, ...] = (),
        winner: int | None = None,
    ) -> None:
        self.current = current
        self.mask = mask
        self._moves = moves
        self._winner = winner

    @property
    def game(self) -> Game:
        """The game: Connect Four."""
        return CONNECT_FOUR

    def is_full(self) -> bool:
        """True when all 42 cells hold a stone."""
        return len(self._moves) == ROWS * COLS

    def can_play(self, col: int) -> bool:
        """True if column ``col`` (0-indexed) is not full."""
        return not self.mask >> (col * _H1 + ROWS - 1) & 1

    def legal_actions(self) -> tuple[int, ...]:
        """The columns that are not full (none once the game is over)."""
        if self._winner is not None:
            return ()
        return tuple(c for c in range(COLS) if self.can_play(c))

    def _apply(self, action: int) -> ConnectFourState:
        mask = self.mask | (self.mask + (1 << (action * _H1)))
        mover = self.current | (mask ^ self.mask)
        winner = self.player if has_four(mover) else None
        return ConnectFourState(mover ^ mask, mask, (*self._moves, action), winner)

    @property
    def key(self) -> int:
        """``current + mask``: one integer that identifies the position."""
        return self.current + self.mask

    def stone(self, row: int, col: int) -> int | None:
        """The player (0/1) whose stone is at (row from the bottom, col), or None."""
        bit = 1 << (col * _H1 + row)
        if not self.mask & bit:
            return None
        return self.player if self.current & bit else 1 - self.player

    def encode(self) -> NDArray[np.float32]:
        """Planes (2, 6, 7) from the top row down: the player to move's stones, then the other's."""
        bits = np.array([self.current, self.current ^ self.mask], dtype=np.uint64)
        return ((bits[:, None, None] >> _CELL_BITS) & np.uint64(1)).astype(np.float32)

    def __str__(self) -> str:
        sym = {None: ".", 0: "X", 1: "O"}
        rows = [
            " ".join(sym[self.stone(r, c)] for c in range(COLS)) for r in range(ROWS - 1, -1, -1)
        ]
        return "\n".join([*rows, " ".join(str(c + 1) for c in range(COLS))])


class ConnectFour(Game):
    """Connect Four: drop stones into 7 columns of 6 rows; four in a line wins."""

    name = "connect-four"
    n_actions = COLS
    rows = ROWS
    cols = COLS
    player_names = ("X", "O")

    def initial(self) -> ConnectFourState:
        """The empty board, X to move."""
        return ConnectFourState()


CONNECT_FOUR = ConnectFour()
