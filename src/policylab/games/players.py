"""Players, named the same way everywhere: ``random``, ``perfect``, ``mcts:N``, a run folder.

A player is anything with ``choose(state) -> action`` (0-indexed) and a ``name``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.games.base import Game, GameState
from policylab.games.mcts import UCT

__all__ = ["MCTSPlayer", "PerfectPlayer", "Player", "RandomPlayer", "make_player"]

PLAYER_HELP = (
    "random (uniform over legal moves), perfect (the exact solver; a random one of the "
    "optimal moves; on Connect Four slow before about 10 stones), mcts:N (UCT with N "
    "random-rollout simulations per move), or a run "
    "folder written by `policylab train selfplay-td|alphazero GAME`"
)


@runtime_checkable
class Player(Protocol):
    """Chooses a move in a non-terminal position."""

    name: str

    def choose(self, state: GameState) -> int:
        """The action (0-indexed) to play in ``state``."""
        ...


class RandomPlayer:
    """Plays a uniformly random legal move."""

    def __init__(self, seed: int | np.random.Generator | None = None) -> None:
        self.name = "random"
        self.rng = np.random.default_rng(seed)

    def choose(self, state: GameState) -> int:
        """A uniformly random legal move."""
        legal = state.legal_actions()
        return int(legal[int(self.rng.integers(len(legal)))])


class PerfectPlayer:
    """Plays an optimal move by the game's exact solver (a random one among ties)."""

    def __init__(self, seed: int | np.random.Generator | None = None) -> None:
        self.name = "perfect"
        self.rng = np.random.default_rng(seed)

    def choose(self, state: GameState) -> int:
        """A uniformly random optimal move."""
        from policylab.games.solvers import best_moves

        best = best_moves(state)
        return int(best[int(self.rng.integers(len(best)))])


class MCTSPlayer:
    """UCT search with random rollouts, N simulations per move."""

    def __init__(self, simulations: int, seed: int | np.random.Generator | None = None) -> None:
        self.name = f"mcts:{simulations}"
        self.search = UCT(simulations, seed=seed)

    def choose(self, state: GameState) -> int:
        """The most visited move after the search."""
        return self.search.choose(state)


def make_player(spec: str, game: Game, seed: int | np.random.Generator | None = None) -> Player:
    """The player a spec names: ``random``, ``perfect``, ``mcts:N`` or a run folder.

    Raises:
        InvalidArgumentError: For an unknown spec, a bad N, or a run of another game.
    """
    s = spec.strip()
    low = s.lower()
    if low == "random":
        return RandomPlayer(seed)
    if low == "perfect":
        return PerfectPlayer(seed)
    if low.startswith("mcts"):
        _, _, n = low.partition(":")
        if not n.isdigit() or int(n) < 1:
            raise InvalidArgumentError(
                f"player {spec!r}: mcts takes a positive number of simulations, as in mcts:200"
            )
        return MCTSPlayer(int(n), seed)
    path = Path(s)
    if path.is_dir():
        from policylab.games.learned import load_player

        return load_player(path, game, seed)
    raise InvalidArgumentError(f"unknown player {spec!r}; a player is {PLAYER_HELP}")
