"""Sutton & Barto's chapter 1 tic-tac-toe learner: a value table learned by self-play.

V(s) estimates, for every position s, the expected result for X (1 a win, 1/2 a draw,
0 a loss); X moves to the position of largest V, O to the smallest. After each greedy
move from S_t to S_{t+1} the earlier position's value moves toward the later one's

    V(S_t) <- V(S_t) + alpha * [V(S_{t+1}) - V(S_t)],

while exploratory moves (random, with probability epsilon) teach nothing. Final
positions hold their result. The step size decays linearly to 0 over training, so
that the table settles (Sutton & Barto, *Reinforcement Learning: An Introduction*,
2nd ed., section 1.5).

Positions are indexed by their base-3 code sum_c cell_c * 3^c (0 empty, 1 X, 2 O).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import InvalidArgumentError
from policylab.games.base import GameState
from policylab.games.tictactoe import TicTacToeState

__all__ = ["SelfPlayTDConfig", "TDPlayer", "position_code", "train_chunk"]

N_CODES = 3**9
_LINES = np.array(
    [[0, 1, 2], [3, 4, 5], [6, 7, 8], [0, 3, 6], [1, 4, 7], [2, 5, 8], [0, 4, 8], [2, 4, 6]],
    dtype=np.int64,
)
_POW3 = 3 ** np.arange(9, dtype=np.int64)


@dataclass(frozen=True)
class SelfPlayTDConfig:
    """Settings of the self-play TD learner (the defaults learn perfect play).

    Attributes:
        episodes: Self-play games in all.
        alpha: Initial step size (decays linearly to 0 over the episodes).
        epsilon: Probability of an exploratory (uniformly random) move.
        seed: Seed of the whole run.
        chunks: Checkpoints written during training (resume continues from the last).
    """

    episodes: int = 200_000
    alpha: float = 0.2
    epsilon: float = 0.2
    seed: int = 0
    chunks: int = 20

    def validate(self) -> None:
        """Raise InvalidArgumentError on a setting outside its range."""
        if not isinstance(self.episodes, int) or self.episodes < 1:
            raise InvalidArgumentError(
                f"episodes must be a positive integer; got {self.episodes!r}"
            )
        if not 0 < self.alpha <= 1:
            raise InvalidArgumentError(f"alpha must be in (0, 1]; got {self.alpha!r}")
        if not 0 <= self.epsilon <= 1:
            raise InvalidArgumentError(f"epsilon must be in [0, 1]; got {self.epsilon!r}")
        if not isinstance(self.chunks, int) or not 1 <= self.chunks <= self.episodes:
            raise InvalidArgumentError(
                f"chunks must be an integer in [1, episodes]; got {self.chunks!r}"
            )

    def to_dict(self) -> dict[str, float | int]:
        """The settings as a JSON-able dict."""
        return dataclasses.asdict(self)


def initial_values() -> NDArray[np.float64]:
    """V before learning: 1/2 everywhere (final positions are set when first reached)."""
    return np.full(N_CODES, 0.5)


@nb.njit(cache=True)
def _result(board: NDArray[np.int64]) -> float:
    """1 if X has a line, 0 if O has, 0.5 for a full board, -1 while the game goes on."""
    for i in range(8):
        a = board[_LINES[i, 0]]
        if a != 0 and a == board[_LINES[i, 1]] and a == board[_LINES[i, 2]]:
            return 1.0 if a == 1 else 0.0
    for c in range(9):
        if board[c] == 0:
            return -1.0
    return 0.5


@nb.njit(cache=True)
def _train(
    V: NDArray[np.float64],
    first: int,
    count: int,
    total: int,
    alpha0: float,
    epsilon: float,
    seed: int,
) -> None:
    np.random.seed(seed)
    board = np.zeros(9, dtype=np.int64)
    moves = np.empty(9, dtype=np.int64)
    after = np.empty(9, dtype=np.int64)
    for ep in range(first, first + count):
        alpha = alpha0 * (1.0 - ep / total)
        board[:] = 0
        code = 0
        mark = 1
        while True:
            k = 0
            for c in range(9):
                if board[c] == 0:
                    moves[k] = c
                    after[k] = code + mark * _POW3[c]
                    k += 1
            greedy = np.random.random() >= epsilon
            if greedy:
                best = -1.0
                n_best = 0
                pick = 0
                for i in range(k):  # X maximises V, O minimises it; ties at random
                    v = V[after[i]] if mark == 1 else 1.0 - V[after[i]]
                    if v > best + 1e-12:
                        best = v
                        n_best = 1
                        pick = i
                    elif abs(v - best) <= 1e-12:
                        n_best += 1
                        if np.random.randint(n_best) == 0:
                            pick = i
            else:
                pick = np.random.randint(k)
            board[moves[pick]] = mark
            nxt = after[pick]
            r = _result(board)
            if r >= 0:
                V[nxt] = r
            if greedy:
                V[code] += alpha * (V[nxt] - V[code])
            if r >= 0:
                break
            code = nxt
            mark = 3 - mark


def train_chunk(
    V: NDArray[np.float64], config: SelfPlayTDConfig, chunk: int
) -> NDArray[np.float64]:
    """Play chunk ``chunk`` (0-based) of the ``config.chunks`` chunks of self-play, in place."""
    config.validate()
    per = config.episodes // config.chunks
    first = chunk * per
    count = per if chunk < config.chunks - 1 else config.episodes - first
    seed = int(np.random.SeedSequence([config.seed, chunk]).generate_state(1)[0] % (2**31 - 1))
    _train(V, first, count, config.episodes, config.alpha, config.epsilon, seed)
    return V


def position_code(state: TicTacToeState) -> int:
    """The base-3 code of a position: sum over cells of (0 empty, 1 X, 2 O) * 3^cell."""
    return int(
        sum(_POW3[c] * (1 if state.x >> c & 1 else 2 if state.o >> c & 1 else 0) for c in range(9))
    )


class TDPlayer:
    """Plays greedily by a learned table: X to the largest V, O to the smallest (ties: first)."""

    def __init__(self, values: NDArray[np.float64], name: str = "selfplay-td") -> None:
        if values.shape != (N_CODES,):
            raise InvalidArgumentError(
                f"a tic-tac-toe value table has {N_CODES} entries; got shape {values.shape}"
            )
        self.values = values
        self.name = name

    def move_values(self, state: GameState) -> dict[int, float]:
        """V of the position after each legal move, from the mover's view."""
        if not isinstance(state, TicTacToeState):
            raise InvalidArgumentError(f"the self-play TD learner plays tic-tac-toe; got {state!r}")
        code = position_code(state)
        mark = 1 + state.player
        out = {}
        for a in state.legal_actions():
            v = float(self.values[code + mark * _POW3[a]])
            out[a] = v if mark == 1 else 1.0 - v
        return out

    def choose(self, state: GameState) -> int:
        """The greedy move (the first one among ties)."""
        mv = self.move_values(state)
        best = max(mv.values())
        return next(a for a, v in mv.items() if v == best)
