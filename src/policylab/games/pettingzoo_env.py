"""Each game as a PettingZoo AEC environment (agents ``player_0`` and ``player_1``).

Observations are dicts like PettingZoo's classic games: ``observation`` is a
(rows, cols, 2) 0/1 array, the observing agent's stones first, and ``action_mask``
marks the legal moves. The reward is +1 / -1 / 0 at the end of the game.
Requires the ``games`` extra (``pip install policylab[games]``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from pettingzoo import AECEnv

from policylab.exceptions import InvalidActionError, InvalidArgumentError
from policylab.games.base import Game, GameState
from policylab.games.registry import get_game

__all__ = ["GameAECEnv", "env", "observation_for"]


def observation_for(state: GameState, player: int) -> dict[str, np.ndarray]:
    """The observation dict of ``player`` (0/1): board planes from their view, and the mask."""
    planes = state.encode()
    if player != state.player:
        planes = planes[::-1]
    obs = np.ascontiguousarray(np.moveaxis(planes, 0, -1)).astype(np.int8)
    mask = state.action_mask() if player == state.player else np.zeros_like(state.action_mask())
    return {"observation": obs, "action_mask": mask}


def observation_space(game: Game) -> gym.spaces.Dict:
    """The observation space of a game's environments."""
    return gym.spaces.Dict(
        {
            "observation": gym.spaces.Box(0, 1, (game.rows, game.cols, 2), dtype=np.int8),
            "action_mask": gym.spaces.Box(0, 1, (game.n_actions,), dtype=np.int8),
        }
    )


class GameAECEnv(AECEnv):  # type: ignore[misc]
    """A policylab game as a PettingZoo AEC environment."""

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["human", "ansi"],
        "name": "policylab_game_v0",
        "is_parallelizable": False,
    }

    def __init__(self, game: str | Game = "tic-tac-toe", render_mode: str | None = None) -> None:
        super().__init__()
        self.game = get_game(game)
        if render_mode not in (None, "human", "ansi"):
            raise InvalidArgumentError(
                f"render_mode must be None, 'human' or 'ansi'; got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.possible_agents = ["player_0", "player_1"]
        self.agents = self.possible_agents[:]
        self.action_spaces = {a: gym.spaces.Discrete(self.game.n_actions) for a in self.agents}
        self.observation_spaces = {a: observation_space(self.game) for a in self.agents}
        self.state_: GameState = self.game.initial()
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos: dict[str, dict[str, Any]] = {a: {} for a in self.agents}
        self.agent_selection = self.agents[0]

    def observation_space(self, agent: str) -> gym.spaces.Space[Any]:
        """The observation space of ``agent``."""
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gym.spaces.Space[Any]:
        """The action space of ``agent``: one action per cell or column."""
        return self.action_spaces[agent]

    def observe(self, agent: str) -> dict[str, np.ndarray]:
        """``agent``'s observation: its stones, the opponent's, and its legal-move mask."""
        return observation_for(self.state_, self.possible_agents.index(agent))

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """Start a new game, player_0 to move."""
        self.state_ = self.game.initial()
        self.agents = self.possible_agents[:]
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {} for a in self.agents}
        self.agent_selection = self.agents[0]

    def step(self, action: int | None) -> None:
        """The selected agent plays ``action``; an illegal move raises InvalidActionError."""
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        if action is None or int(action) not in self.state_.legal_actions():
            raise InvalidActionError(
                f"{self.game.name}: {agent} played {action!r}, which is not legal in position "
                f"{self.state_.position_string()!r}; legal actions (0-indexed) are "
                f"{list(self.state_.legal_actions())}"
            )
        self.state_ = self.state_.play(int(action))
        self._cumulative_rewards[agent] = 0.0
        self.rewards = {a: 0.0 for a in self.agents}
        if self.state_.is_terminal():
            for i, a in enumerate(self.possible_agents):
                self.rewards[a] = self.state_.outcome(i)
                self.terminations[a] = True
        self.agent_selection = self.possible_agents[self.state_.player]
        self._accumulate_rewards()
        if self.render_mode == "human":
            self.render()

    def render(self) -> str | None:
        """The board as text ('ansi' returns it, 'human' prints it)."""
        text = str(self.state_)
        if self.render_mode == "human":
            print(text)
            return None
        return text

    def close(self) -> None:
        """Nothing to release."""


def env(game: str | Game = "tic-tac-toe", render_mode: str | None = None) -> GameAECEnv:
    """A game's AEC environment (``env("connect-four")``)."""
    return GameAECEnv(game, render_mode=render_mode)
