"""UCT: Monte Carlo tree search with random rollouts (Kocsis & Szepesvári, 2006).

Each simulation walks down the tree choosing the child with the largest upper
confidence bound (UCB1)

    Q(s, a) + c * sqrt(ln N(s) / N(s, a)),

adds one new child, plays uniformly random moves from it to the end of the game
(a rollout) and backs the outcome up the path, each node keeping the mean outcome
for the player who moved into it. The move played is the most visited child of the
root. On Connect Four the whole search is compiled (:func:`policylab.games._c4.uct_search`:
the tree in arrays, playouts on the bitboards); other games run it in Python.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import InvalidArgumentError
from policylab.games.base import GameState
from policylab.games.connect_four import ConnectFourState

__all__ = ["UCT", "rollout_outcome"]


def rollout_outcome(state: GameState, rng: np.random.Generator) -> float:
    """Outcome for the player to move in ``state`` after uniformly random play to the end."""
    if isinstance(state, ConnectFourState):
        from policylab.games import _c4

        if state.is_terminal():
            return state.outcome(state.player)
        return float(
            _c4.rollout(
                np.uint64(state.current),
                np.uint64(state.mask),
                int(rng.integers(2**31 - 1)),
            )
        )
    player = state.player
    s = state
    while not s.is_terminal():
        legal = s.legal_actions()
        s = s._apply(legal[int(rng.integers(len(legal)))])
    return s.outcome(player)


class _Node:
    __slots__ = ("children", "n", "state", "untried", "w")

    def __init__(self, state: GameState, rng: np.random.Generator) -> None:
        self.state = state
        self.children: dict[int, _Node] = {}
        actions = list(state.legal_actions())
        rng.shuffle(actions)
        self.untried = actions
        self.n = 0
        self.w = 0.0  # total outcome for the player who moved into this node


class UCT:
    """UCT search with ``simulations`` rollouts per move.

    Args:
        simulations: Simulations (selection, expansion, rollout, backup) per move.
        c: Exploration constant of UCB1 (sqrt(2) for outcomes in [-1, 1] scaled to [0, 1]
            is the textbook choice; 1.4 here on outcomes in [-1, 1]).
        seed: Seed of the rollouts and of tie-breaking.
    """

    def __init__(
        self, simulations: int, c: float = 1.4, seed: int | np.random.Generator | None = None
    ) -> None:
        if not isinstance(simulations, int) or simulations < 1:
            raise InvalidArgumentError(
                f"mcts needs a positive number of simulations; got {simulations!r}"
            )
        if not c >= 0:
            raise InvalidArgumentError(f"the UCT exploration constant must be >= 0; got {c!r}")
        self.simulations = simulations
        self.c = c
        self.rng = np.random.default_rng(seed)

    def visit_counts(self, state: GameState) -> NDArray[np.int64]:
        """N(s0, a) for every action after the search (0 for illegal actions)."""
        if state.is_terminal():
            raise InvalidArgumentError(
                f"{state.game.name}: cannot search from a finished game "
                f"({state.position_string()!r})"
            )
        if isinstance(state, ConnectFourState):  # the same search, compiled
            from policylab.games import _c4

            return _c4.uct_search(
                np.uint64(state.current),
                np.uint64(state.mask),
                self.simulations,
                float(self.c),
                int(self.rng.integers(2**31 - 1)),
            )
        root = _Node(state, self.rng)
        for _ in range(self.simulations):
            self._simulate(root)
        counts = np.zeros(state.game.n_actions, dtype=np.int64)
        for a, ch in root.children.items():
            counts[a] = ch.n
        return counts

    def choose(self, state: GameState) -> int:
        """The most visited root move (ties broken at random)."""
        counts = self.visit_counts(state)
        best = np.flatnonzero(counts == counts.max())
        return int(best[self.rng.integers(len(best))])

    def _simulate(self, root: _Node) -> None:
        path = [root]
        node = root
        # selection: descend through fully expanded nodes by UCB1
        while not node.untried and node.children:
            log_n = math.log(node.n)
            best_score = -math.inf
            best = node
            for ch in node.children.values():
                score = ch.w / ch.n + self.c * math.sqrt(log_n / ch.n)
                if score > best_score:
                    best_score, best = score, ch
            node = best
            path.append(node)
        # expansion
        if node.untried:
            a = node.untried.pop()
            child = _Node(node.state._apply(a), self.rng)
            node.children[a] = child
            node = child
            path.append(node)
        # rollout: outcome for the player to move at the leaf
        s = node.state
        value = s.outcome(s.player) if s.is_terminal() else rollout_outcome(s, self.rng)
        # backup: each node stores the outcome for the player who moved into it
        for nd in reversed(path):
            value = -value
            nd.n += 1
            nd.w += value
