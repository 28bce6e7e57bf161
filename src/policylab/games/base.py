"""The interface of a two-player, turn-based, zero-sum game with perfect information.

A game is a :class:`Game` (its name, its actions, its first position) and its positions
are immutable :class:`GameState` objects: the player to move, the legal actions, the
position after an action, whether the game is over and its outcome from each player's
view (+1 a win, -1 a loss, 0 a draw: the reward the "Deep Reinforcement Learning"
lecture notes give board games). Players are numbered 0 (moves first) and 1.

Positions are written as the sequence of moves played, one digit per move, 1-indexed
(tic-tac-toe: cells 1-9 row by row from the top left; Connect Four: columns 1-7).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import InvalidActionError, InvalidArgumentError

__all__ = ["Game", "GameState"]

S = TypeVar("S", bound="GameState")


class GameState(ABC):
    """One position of a game; immutable (``play`` returns a new position)."""

    __slots__ = ("_moves", "_winner")

    _moves: tuple[int, ...]
    _winner: int | None

    @property
    @abstractmethod
    def game(self) -> Game:
        """The game this position belongs to."""

    @property
    def moves(self) -> tuple[int, ...]:
        """The actions played from the first position to this one (0-indexed)."""
        return self._moves

    @property
    def player(self) -> int:
        """The player to move: 0 (moved first) or 1."""
        return len(self._moves) & 1

    @property
    def winner(self) -> int | None:
        """The player who has won, or None (game going on, or drawn)."""
        return self._winner

    @abstractmethod
    def legal_actions(self) -> tuple[int, ...]:
        """The actions the player to move may take, in increasing order (empty at the end)."""

    @abstractmethod
    def _apply(self: S, action: int) -> S:
        """The position after a legal ``action`` (checked by :meth:`play`)."""

    @abstractmethod
    def is_full(self) -> bool:
        """True if no move is left (with no winner, a draw)."""

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """A hashable key identifying the position (independent of move order)."""

    @abstractmethod
    def encode(self) -> NDArray[np.float32]:
        """Planes (2, rows, cols): the stones of the player to move, then the opponent's."""

    @abstractmethod
    def __str__(self) -> str:
        """The board as text."""

    def is_terminal(self) -> bool:
        """True once a player has won or the board is full."""
        return self.winner is not None or self.is_full()

    def play(self: S, action: int) -> S:
        """The position after the player to move takes ``action`` (0-indexed).

        Raises:
            InvalidActionError: If the game is over or ``action`` is not legal here.
        """
        if self.is_terminal():
            raise InvalidActionError(
                f"{self.game.name}: no move is allowed after the end of the game "
                f"(position {self.position_string()!r}: {self.result_text()}); "
                f"got move {action + 1}"
            )
        legal = self.legal_actions()
        if not isinstance(action, int | np.integer) or int(action) not in legal:
            raise InvalidActionError(
                f"{self.game.name}: move {_shown(action)} is not legal in position "
                f"{self.position_string()!r}; legal moves are "
                f"{', '.join(str(a + 1) for a in legal)}"
            )
        return self._apply(int(action))

    def outcome(self, player: int) -> float:
        """+1 if ``player`` won, -1 if they lost, 0 for a draw.

        Raises:
            InvalidArgumentError: If the game is not over or ``player`` is not 0 or 1.
        """
        if player not in (0, 1):
            raise InvalidArgumentError(f"player must be 0 or 1; got {player!r}")
        if not self.is_terminal():
            raise InvalidArgumentError(
                f"{self.game.name}: position {self.position_string()!r} is not over; "
                "an outcome exists only at the end of the game"
            )
        w = self.winner
        return 0.0 if w is None else (1.0 if w == player else -1.0)

    def position_string(self) -> str:
        """The moves played, 1-indexed, as accepted by :meth:`Game.from_moves`."""
        return "".join(str(a + 1) for a in self.moves)

    def result_text(self) -> str:
        """'X wins', 'a draw' or 'X to move' in the game's own names for the players."""
        names = self.game.player_names
        if self.winner is not None:
            return f"{names[self.winner]} won"
        if self.is_full():
            return "a draw"
        return f"{names[self.player]} to move"

    def action_mask(self) -> NDArray[np.int8]:
        """A 0/1 vector over all actions of the game: 1 where the action is legal."""
        mask = np.zeros(self.game.n_actions, dtype=np.int8)
        mask[list(self.legal_actions())] = 1
        return mask

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, GameState)
            and self.game.name == other.game.name
            and (self.key == other.key)
        )

    def __hash__(self) -> int:
        return hash((self.game.name, self.key))

    def __repr__(self) -> str:
        return f"<{self.game.name} {self.position_string()!r}: {self.result_text()}>"


class Game(ABC):
    """A two-player zero-sum game: its name, action count, board shape and first position."""

    name: str
    n_actions: int
    rows: int
    cols: int
    player_names: tuple[str, str]

    @abstractmethod
    def initial(self) -> GameState:
        """The first position (player 0 to move)."""

    def from_moves(self, moves: str | Any) -> GameState:
        """The position reached by a string of 1-indexed moves (``"4455"``; "" is the start).

        Raises:
            InvalidArgumentError: If ``moves`` is not a string of digits 1..n_actions.
            InvalidActionError: If a move is illegal or comes after the end of the game.
        """
        if not isinstance(moves, str):
            raise InvalidArgumentError(
                f"{self.name}: a position is a string of moves such as '4455'; "
                f"got {type(moves).__name__}"
            )
        text = moves.strip()
        state = self.initial()
        for i, ch in enumerate(text):
            if not ch.isdigit() or not 1 <= int(ch) <= self.n_actions:
                raise InvalidArgumentError(
                    f"{self.name}: malformed position {moves!r}: character {i + 1} is {ch!r}; "
                    f"each move is one digit from 1 to {self.n_actions}"
                )
            a = int(ch) - 1
            if state.is_terminal():
                raise InvalidActionError(
                    f"{self.name}: position {moves!r} goes on after the end of the game: "
                    f"move {i + 1} ({ch}) comes after {state.result_text()}"
                )
            if a not in state.legal_actions():
                raise InvalidActionError(
                    f"{self.name}: position {moves!r} has an illegal move {i + 1} ({ch}); "
                    f"legal moves there are {', '.join(str(b + 1) for b in state.legal_actions())}"
                )
            state = state._apply(a)
        return state

    def __repr__(self) -> str:
        return f"<game {self.name}>"


def _shown(action: object) -> str:
    """An action as the user numbers it (1-indexed), or its repr if not an integer."""
    if isinstance(action, int | np.integer):
        return str(int(action) + 1)
    return repr(action)
