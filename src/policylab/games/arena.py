"""Matches between two players, colours alternating, with confidence intervals."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from policylab.exceptions import InvalidArgumentError
from policylab.games.base import Game, GameState
from policylab.games.players import Player

__all__ = ["ArenaResult", "arena", "play_game", "wilson_interval", "worst_outcome"]


def wilson_interval(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a proportion: k successes in n trials (95% by default).

    With p = k / n (Wilson, 1927, *J. Amer. Statist. Assoc.* 22:209-212):

        centre     = (p + z^2 / 2n) / (1 + z^2 / n)
        half-width = z / (1 + z^2 / n) * sqrt(p (1 - p) / n + z^2 / 4n^2)

    and the interval is [centre - half-width, centre + half-width]. Unlike the normal
    approximation p +- z sqrt(p (1 - p) / n) it stays inside [0, 1] and does not
    collapse to a point at k = 0 or k = n.

    Args:
        k: Successes (0 <= k <= n).
        n: Trials; with none, nothing is known and the interval is [0, 1].
        z: The standard normal quantile of the confidence level (1.96: 95%).

    Returns:
        (lower, upper) bounds of the interval.

    Raises:
        InvalidArgumentError: If n < 0, k is outside [0, n], or z <= 0.
    """
    if n < 0 or not 0 <= k <= max(n, 0) or not z > 0:
        raise InvalidArgumentError(
            f"wilson_interval needs 0 <= k <= n and z > 0; got k={k!r}, n={n!r}, z={z!r}"
        )
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    d = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / d
    half = z / d * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (max(0.0, centre - half), min(1.0, centre + half))


@dataclass(frozen=True)
class ArenaResult:
    """Wins, draws and losses from the first player's (A's) view."""

    a: str
    b: str
    wins: int
    draws: int
    losses: int

    @property
    def games(self) -> int:
        """Games played."""
        return self.wins + self.draws + self.losses

    def interval(self, what: str) -> tuple[float, float]:
        """95% Wilson interval of the share of 'wins', 'draws' or 'losses'."""
        return wilson_interval(getattr(self, what), self.games)

    def to_json(self) -> dict[str, int]:
        """``{"wins", "draws", "losses", "games"}``."""
        return {
            "wins": self.wins,
            "draws": self.draws,
            "losses": self.losses,
            "games": self.games,
        }


def play_game(first: Player, second: Player, start: GameState) -> GameState:
    """Play from ``start`` to the end, ``first`` moving for player 0; the final position."""
    s = start
    players = (first, second)
    while not s.is_terminal():
        s = s.play(players[s.player].choose(s))
    return s


def worst_outcome(
    player: Player,
    start: GameState,
    me: int,
    opponent_moves: Callable[[GameState], tuple[int, ...]],
) -> float:
    """``player``'s worst result (as ``me``) over every line of the opponent's allowed moves.

    ``player`` must be deterministic; ``opponent_moves`` gives the moves the opponent may
    make in a position: every legal move, or (with :func:`~policylab.games.best_moves`)
    every optimal one, so that 0 means "never loses to perfect play".
    """
    if start.is_terminal():
        return start.outcome(me)
    if start.player == me:
        return worst_outcome(player, start.play(player.choose(start)), me, opponent_moves)
    return min(
        worst_outcome(player, start.play(a), me, opponent_moves) for a in opponent_moves(start)
    )


def arena(
    game: Game,
    a: Player,
    b: Player,
    games: int,
    on_game: Callable[[int], None] | None = None,
) -> ArenaResult:
    """Play ``games`` games, A moving first in the even-numbered ones; results from A's view."""
    if not isinstance(games, int) or games < 1:
        raise InvalidArgumentError(f"--games must be a positive integer; got {games!r}")
    w = d = lo = 0
    for i in range(games):
        a_first = i % 2 == 0
        end = play_game(a, b, game.initial()) if a_first else play_game(b, a, game.initial())
        r = end.outcome(0 if a_first else 1)
        if r > 0:
            w += 1
        elif r < 0:
            lo += 1
        else:
            d += 1
        if on_game is not None:
            on_game(i + 1)
    return ArenaResult(a.name, b.name, w, d, lo)
