"""Two-player zero-sum board games: rules, exact solvers, tree search, self-play learners.

    from policylab.games import get_game, solve_tic_tac_toe, connect_four_solver
    ttt = get_game("tic-tac-toe")
    solve_tic_tac_toe().value(ttt.initial())                              # 0: a draw
    connect_four_solver().score(get_game("connect-four").from_moves("4455"))  # 18

Players (``random``, ``perfect``, ``mcts:N``, a run folder) come from
:func:`make_player` and meet in :func:`arena`.
"""

from policylab.games.arena import ArenaResult, arena, play_game, wilson_interval
from policylab.games.base import Game, GameState
from policylab.games.connect_four import CONNECT_FOUR, ConnectFour, ConnectFourState
from policylab.games.mcts import UCT
from policylab.games.players import MCTSPlayer, PerfectPlayer, Player, RandomPlayer, make_player
from policylab.games.registry import GAMES, get_game, is_game
from policylab.games.solvers import (
    ConnectFourSolver,
    TicTacToeSolution,
    best_moves,
    connect_four_solver,
    solve_tic_tac_toe,
)
from policylab.games.tictactoe import TIC_TAC_TOE, TicTacToe, TicTacToeState

__all__ = [
    "CONNECT_FOUR",
    "GAMES",
    "TIC_TAC_TOE",
    "UCT",
    "ArenaResult",
    "ConnectFour",
    "ConnectFourSolver",
    "ConnectFourState",
    "Game",
    "GameState",
    "MCTSPlayer",
    "PerfectPlayer",
    "Player",
    "RandomPlayer",
    "TicTacToe",
    "TicTacToeSolution",
    "TicTacToeState",
    "arena",
    "best_moves",
    "connect_four_solver",
    "get_game",
    "is_game",
    "make_player",
    "play_game",
    "solve_tic_tac_toe",
    "wilson_interval",
]
