"""Exact solutions: tic-tac-toe solved completely, Connect Four by negamax search.

Values and scores are from the view of the player to move. Tic-tac-toe: +1 a win,
0 a draw, -1 a loss under perfect play. Connect Four: Pascal Pons' score, positive
when the player to move wins (22 - k for a win with their k-th stone, so faster
wins score higher), the negative of that for a loss, 0 for a draw.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.games.base import GameState
from policylab.games.connect_four import ConnectFourState
from policylab.games.tictactoe import TIC_TAC_TOE, TicTacToeState

__all__ = [
    "ConnectFourSolver",
    "TicTacToeSolution",
    "best_moves",
    "connect_four_solver",
    "solve_tic_tac_toe",
]


@dataclass(frozen=True)
class TicTacToeSolution:
    """The value under perfect play of every reachable tic-tac-toe position.

    Attributes:
        values: Position key ``(X cells, O cells)`` -> value for the player to move
            (+1 win, 0 draw, -1 loss); terminal positions included.
    """

    values: dict[tuple[int, int], int]

    @property
    def n_positions(self) -> int:
        """How many positions are reachable from the empty board (5,478)."""
        return len(self.values)

    def value(self, state: TicTacToeState) -> int:
        """v(s) for the player to move: max over moves a of -v(s after a)."""
        return self.values[_ttt(state).key]

    def move_values(self, state: TicTacToeState) -> dict[int, int]:
        """The value of each legal move for the player to move: -v(position after it)."""
        s = _ttt(state)
        return {a: -self.values[s._apply(a).key] for a in s.legal_actions()}

    def best_moves(self, state: TicTacToeState) -> tuple[int, ...]:
        """Every optimal move (0-indexed cells) of a non-terminal position."""
        mv = self.move_values(state)
        if not mv:
            return ()
        best = max(mv.values())
        return tuple(a for a, v in mv.items() if v == best)


def _ttt(state: GameState) -> TicTacToeState:
    if not isinstance(state, TicTacToeState):
        raise InvalidArgumentError(f"expected a tic-tac-toe position; got {state!r}")
    return state


@functools.cache
def solve_tic_tac_toe() -> TicTacToeSolution:
    """Solve tic-tac-toe: negamax over every position reachable from the empty board."""
    values: dict[tuple[int, int], int] = {}

    def negamax(s: TicTacToeState) -> int:
        k = s.key
        if k in values:
            return values[k]
        if s.is_terminal():
            v = int(s.outcome(s.player))
        else:
            v = max(-negamax(s._apply(a)) for a in s.legal_actions())
        values[k] = v
        return v

    negamax(TIC_TAC_TOE.initial())
    return TicTacToeSolution(values)


@dataclass
class ConnectFourSolver:
    """Exact Connect Four scores by compiled negamax (alpha-beta, transposition table).

    The transposition table (about 72 MB by default) is kept between calls, so
    solving many positions of one game gets faster as it fills.

    Attributes:
        table_size: Entries of the transposition table (a prime works best).
        nodes: Positions searched so far, over all calls.
    """

    table_size: int = 0
    nodes: int = 0
    _keys: np.ndarray = field(init=False, repr=False)
    _vals: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        from policylab.games import _c4

        if self.table_size == 0:
            self.table_size = _c4.TT_SIZE
        if self.table_size < 1:
            raise InvalidArgumentError(f"table_size must be positive; got {self.table_size}")
        self._keys, self._vals = _c4.new_table(self.table_size)

    def _check(self, state: GameState) -> ConnectFourState:
        if not isinstance(state, ConnectFourState):
            raise InvalidArgumentError(f"expected a Connect Four position; got {state!r}")
        if state.is_terminal():
            raise InvalidArgumentError(
                f"connect-four: position {state.position_string()!r} is over "
                f"({state.result_text()}); only positions with a move to make have a score"
            )
        return state

    def score(self, state: ConnectFourState) -> int:
        """The position's score for the player to move (Pons' convention)."""
        from policylab.games import _c4

        s = self._check(state)
        counter = np.zeros(1, dtype=np.int64)
        out = _c4.solve(
            np.uint64(s.current), np.uint64(s.mask), len(s.moves), self._keys, self._vals, counter
        )
        self.nodes += int(counter[0])
        return int(out)

    def move_scores(self, state: ConnectFourState) -> dict[int, int]:
        """The score of each legal move for the player making it (0-indexed columns)."""
        from policylab.games import _c4

        s = self._check(state)
        counter = np.zeros(1, dtype=np.int64)
        out = _c4.solve_moves(
            np.uint64(s.current), np.uint64(s.mask), len(s.moves), self._keys, self._vals, counter
        )
        self.nodes += int(counter[0])
        return {a: int(out[a]) for a in s.legal_actions()}

    def best_moves(self, state: ConnectFourState) -> tuple[int, ...]:
        """Every move that keeps the position's score (0-indexed columns)."""
        mv = self.move_scores(state)
        best = max(mv.values())
        return tuple(a for a, v in mv.items() if v == best)

    def timed_score(self, state: ConnectFourState) -> tuple[int, float, int]:
        """(score, seconds, nodes searched) of one position."""
        before = self.nodes
        t0 = time.perf_counter()
        sc = self.score(state)
        return sc, time.perf_counter() - t0, self.nodes - before


@functools.cache
def connect_four_solver() -> ConnectFourSolver:
    """The process's shared Connect Four solver (one transposition table)."""
    return ConnectFourSolver()


def best_moves(state: GameState) -> tuple[int, ...]:
    """Every optimal move of a non-terminal position, by the game's exact solver."""
    if isinstance(state, TicTacToeState):
        return solve_tic_tac_toe().best_moves(state)
    if isinstance(state, ConnectFourState):
        return connect_four_solver().best_moves(state)
    raise InvalidArgumentError(f"no exact solver for {state.game.name}")
