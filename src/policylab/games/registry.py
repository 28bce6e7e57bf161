"""The games by their command-line names."""

from __future__ import annotations

from policylab.exceptions import UnknownProblemError
from policylab.games.base import Game
from policylab.games.connect_four import CONNECT_FOUR
from policylab.games.tictactoe import TIC_TAC_TOE

__all__ = ["GAMES", "get_game", "is_game"]

GAMES: dict[str, Game] = {g.name: g for g in (TIC_TAC_TOE, CONNECT_FOUR)}
_ALIASES = {"tictactoe": "tic-tac-toe", "connect4": "connect-four", "connectfour": "connect-four"}


def _key(name: str) -> str:
    k = name.strip().lower().replace("_", "-")
    return _ALIASES.get(k.replace("-", ""), k)


def is_game(name: str) -> bool:
    """True if ``name`` names a board game (``tic-tac-toe``, ``connect-four``)."""
    return _key(name) in GAMES


def get_game(name: str | Game) -> Game:
    """The game called ``name`` (hyphens or underscores, any case).

    Raises:
        UnknownProblemError: If no game has that name.
    """
    if isinstance(name, Game):
        return name
    k = _key(name)
    if k not in GAMES:
        raise UnknownProblemError(f"unknown game {name!r}; known games: {', '.join(GAMES)}")
    return GAMES[k]
