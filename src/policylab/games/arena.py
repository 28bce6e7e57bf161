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

    The value is the minimax one over the lines,
    W(s) = outcome(s) at the end, W(s') for the player's move s -> s', and the minimum of
    W over the opponent's allowed moves; each position is visited once however many
    move orders reach it (the player's move depends on the position only), a number of
    stones at a time, so that a player with ``choose_many`` searches all its positions
    with as many stones in one call.
    """
    layers: list[list[GameState]] = []
    children: dict[GameState, list[GameState]] = {}
    seen = {start}
    layer = [start]
    while layer:
        layers.append(layer)
        mine = [s for s in layer if not s.is_terminal() and s.player == me]
        for s, a in zip(mine, _choose_all(player, mine), strict=True):
            children[s] = [s.play(a)]
        for s in layer:
            if not s.is_terminal() and s.player != me:
                children[s] = [s.play(a) for a in opponent_moves(s)]
        layer = []
        for s in layers[-1]:
            for c in children.get(s, ()):
                if c not in seen:  # a position has the same number of stones on every line
                    seen.add(c)
                    layer.append(c)
    value: dict[GameState, float] = {}
    for layer in reversed(layers):
        for s in layer:
            value[s] = s.outcome(me) if s.is_terminal() else min(value[c] for c in children[s])
    return value[start]


def _choose_all(player: Player, states: list[GameState]) -> list[int]:
    """``player``'s move in each position: one batched call if it has ``choose_many``."""
    many = getattr(player, "choose_many", None)
    if many is not None and states:
        return [int(m) for m in many(states)]
    return [player.choose(s) for s in states]


def play_side_by_side(
    starts: list[GameState],
    a: Player,
    b: Player,
    a_colours: list[int],
    on_game: Callable[[int], None] | None = None,
) -> list[GameState]:
    """Play every game from its start to the end at once; the final positions, in order.

    A plays colour ``a_colours[i]`` (0 moves first) in game i. A player with a
    ``choose_many(states)`` method gets all its positions of a turn in one call (an
    AlphaZero player searches them together, its network evaluating their leaves in one
    batch); others are asked position by position. ``on_game`` gets the number of games
    finished whenever it grows.
    """
    states = list(starts)
    live = [i for i, s in enumerate(states) if not s.is_terminal()]
    finished = len(states) - len(live)
    while live:
        for player, a_moves in ((a, True), (b, False)):
            idx = [
                i
                for i in live
                if not states[i].is_terminal() and (states[i].player == a_colours[i]) == a_moves
            ]
            if idx:
                for i, m in zip(idx, _choose_all(player, [states[i] for i in idx]), strict=True):
                    states[i] = states[i].play(m)
        live = [i for i in live if not states[i].is_terminal()]
        if on_game is not None and len(states) - len(live) > finished:
            finished = len(states) - len(live)
            on_game(finished)
    return states


def arena(
    game: Game,
    a: Player,
    b: Player,
    games: int,
    on_game: Callable[[int], None] | None = None,
    finals: list[GameState] | None = None,
) -> ArenaResult:
    """Play ``games`` games, A moving first in the even-numbered ones; results from A's view.

    Args:
        game: The game.
        a: Player A (the results are from A's view).
        b: Player B.
        games: Games to play; colours alternate.
        on_game: Called with the number of games finished so far.
        finals: If given, the final position of every game is appended to it, in order.

    If either player has ``choose_many`` (an AlphaZero player), the games are played side
    by side (:func:`play_side_by_side`), else one after the other.
    """
    if not isinstance(games, int) or games < 1:
        raise InvalidArgumentError(f"--games must be a positive integer; got {games!r}")
    colours = [i % 2 for i in range(games)]  # A's colour: first in the even games
    if hasattr(a, "choose_many") or hasattr(b, "choose_many"):
        ends = play_side_by_side([game.initial() for _ in range(games)], a, b, colours, on_game)
    else:
        ends = []
        for i in range(games):
            first, second = (a, b) if colours[i] == 0 else (b, a)
            ends.append(play_game(first, second, game.initial()))
            if on_game is not None:
                on_game(i + 1)
    outcomes = [end.outcome(c) for end, c in zip(ends, colours, strict=True)]
    if finals is not None:
        finals.extend(ends)
    return ArenaResult(
        a.name,
        b.name,
        sum(r > 0 for r in outcomes),
        sum(r == 0 for r in outcomes),
        sum(r < 0 for r in outcomes),
    )
