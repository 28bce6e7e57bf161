"""A game against a fixed opponent as a single-agent Gymnasium environment.

The agent plays one side (``play_as`` 0: first, 1: second) and the opponent (any
player spec: ``random``, ``perfect``, ``mcts:N``, a run folder) answers each move.
Observations are ``{"observation": (rows, cols, 2), "action_mask": (n_actions,)}``
from the agent's view; the reward is +1 / -1 / 0 when the game ends (terminated).
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from policylab.exceptions import InvalidActionError, InvalidArgumentError
from policylab.games.base import Game, GameState
from policylab.games.players import Player, make_player
from policylab.games.registry import get_game

__all__ = ["GameEnv"]


class GameEnv(gym.Env[dict[str, np.ndarray], int]):
    """A board game against a fixed opponent, with the legal moves in ``action_mask``.

    Args:
        game: The game (name or object).
        opponent: The opponent's player spec or a player object.
        play_as: 0 to move first, 1 to move second.
        render_mode: None or 'ansi' (``render()`` returns the board as text).
    """

    metadata = {"render_modes": ["ansi"]}  # noqa: RUF012

    def __init__(
        self,
        game: str | Game = "tic-tac-toe",
        opponent: str | Player = "random",
        play_as: int = 0,
        render_mode: str | None = None,
    ) -> None:
        from policylab.games.pettingzoo_env import observation_space

        self.game = get_game(game)
        if play_as not in (0, 1):
            raise InvalidArgumentError(f"play_as must be 0 or 1; got {play_as!r}")
        if render_mode not in (None, "ansi"):
            raise InvalidArgumentError(f"render_mode must be None or 'ansi'; got {render_mode!r}")
        self.render_mode = render_mode
        self.play_as = play_as
        self._opponent_spec = opponent
        self.opponent: Player | None = None if isinstance(opponent, str) else opponent
        self.action_space = gym.spaces.Discrete(self.game.n_actions)  # type: ignore[assignment]
        self.observation_space = observation_space(self.game)  # type: ignore[assignment]
        self.state: GameState = self.game.initial()

    def _obs(self) -> dict[str, np.ndarray]:
        from policylab.games.pettingzoo_env import observation_for

        return observation_for(self.state, self.play_as)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """A new game; the opponent moves first when the agent plays second."""
        super().reset(seed=seed)
        if isinstance(self._opponent_spec, str) and (self.opponent is None or seed is not None):
            self.opponent = make_player(self._opponent_spec, self.game, self.np_random)
        self.state = self.game.initial()
        if self.play_as == 1:
            assert self.opponent is not None
            self.state = self.state.play(self.opponent.choose(self.state))
        return self._obs(), {}

    def step(
        self, action: int
    ) -> tuple[dict[str, np.ndarray], SupportsFloat, bool, bool, dict[str, Any]]:
        """Play ``action``, then the opponent's answer; reward at the end of the game."""
        if self.state.is_terminal():
            raise InvalidActionError(
                f"{self.game.name}: step() after the end of the game; call reset()"
            )
        a = int(action)
        if a not in self.state.legal_actions():
            raise InvalidActionError(
                f"{self.game.name}: action {a} is not legal in position "
                f"{self.state.position_string()!r}; legal actions (0-indexed) are "
                f"{list(self.state.legal_actions())} (see obs['action_mask'])"
            )
        self.state = self.state.play(a)
        if not self.state.is_terminal():
            assert self.opponent is not None
            self.state = self.state.play(self.opponent.choose(self.state))
        done = self.state.is_terminal()
        reward = self.state.outcome(self.play_as) if done else 0.0
        return self._obs(), reward, done, False, {}

    def render(self) -> str | None:
        """The board as text."""
        return str(self.state)
