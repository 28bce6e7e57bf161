"""The agent-environment loop (notes section 4): a Gymnasium env for any FiniteMDP."""

from __future__ import annotations

from typing import Any, Literal

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from policylab.exceptions import InvalidActionError, InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.validation import check_count, check_seed

__all__ = ["MDPEnv", "make_problem_env"]


class MDPEnv(gym.Env[np.int64, np.int64]):
    """A ``gymnasium.Env`` that simulates a :class:`FiniteMDP`.

    Observations and actions are indices (``Discrete(S)`` and ``Discrete(A)``) in the
    order of ``mdp.states`` and ``mdp.actions``. ``reset`` draws S_0 from the MDP's
    start distribution; ``step`` draws (S_{t+1}, R_{t+1}) from p(s', r | s, a).
    ``terminated`` is True on reaching a terminal state (S+ minus S); ``truncated`` is
    True when ``max_steps`` steps have passed without termination, which continuing
    tasks (the recycling robot) need. ``info`` holds ``action_mask``, the int8 mask of
    A(s) for the current state, and ``state``, its label.

    Args:
        mdp: The MDP to simulate.
        max_steps: Optional step limit (truncation).
        invalid_action: What an action outside A(s) does: ``"raise"`` an
            :class:`~policylab.exceptions.InvalidActionError`, or ``"stay"``: the state
            does not change and the reward is ``invalid_reward``.
        invalid_reward: Reward of an invalid action under ``"stay"``.
        render_mode: ``"ansi"`` for a text rendering, or None.
    """

    metadata = {"render_modes": ["ansi"]}  # noqa: RUF012

    def __init__(
        self,
        mdp: FiniteMDP,
        max_steps: int | None = None,
        invalid_action: Literal["raise", "stay"] = "stay",
        invalid_reward: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        if not isinstance(mdp, FiniteMDP):
            raise InvalidArgumentError(
                f"MDPEnv wraps a FiniteMDP; got {type(mdp).__name__} {mdp!r:.60}"
            )
        if max_steps is not None:
            max_steps = check_count(max_steps, "max_steps (a positive integer or None)")
        if invalid_action not in ("raise", "stay"):
            raise InvalidArgumentError(
                f"invalid_action must be 'raise' or 'stay'; got {invalid_action!r}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidArgumentError(
                f"render_mode must be one of {self.metadata['render_modes']}"
            )
        self.mdp = mdp
        self.max_steps = max_steps
        self.invalid_action = invalid_action
        self.invalid_reward = float(invalid_reward)
        self.render_mode = render_mode
        self.observation_space = spaces.Discrete(mdp.n_states)
        self.action_space = spaces.Discrete(mdp.n_actions)
        self._state = -1
        self._t = 0
        self._masks = mdp.action_mask.astype(np.int8)

    @property
    def state(self) -> int:
        """The current state index (-1 before the first reset)."""
        return self._state

    def _info(self) -> dict[str, Any]:
        return {
            "action_mask": self._masks[self._state].copy(),
            "state": self.mdp.states[self._state],
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.int64, dict[str, Any]]:
        """Start an episode in a state drawn from the start distribution.

        ``options={"state": label}`` starts in a given non-terminal state instead.
        """
        super().reset(seed=check_seed(seed))
        if options and "state" in options:
            s = self.mdp.state_index(options["state"])
            if self.mdp.terminal[s]:
                raise InvalidArgumentError(f"cannot start in terminal state {options['state']!r}")
            self._state = s
        else:
            self._state = self.mdp.sample_initial(self.np_random)
        self._t = 0
        return np.int64(self._state), self._info()

    def step(self, action: Any) -> tuple[np.int64, float, bool, bool, dict[str, Any]]:
        """Take action A_t; return S_{t+1}, R_{t+1}, terminated, truncated, info."""
        if self._state < 0:
            raise InvalidArgumentError("call reset() before step()")
        if self.mdp.terminal[self._state]:
            raise InvalidActionError("the episode has terminated; call reset()")
        if isinstance(action, np.ndarray) and action.shape == ():
            action = action.item()
        if isinstance(action, bool | np.bool_) or not isinstance(action, int | np.integer):
            raise InvalidActionError(
                f"action must be an index in Discrete({self.mdp.n_actions}); got "
                f"{type(action).__name__} {action!r}"
            )
        a = int(action)
        if not 0 <= a < self.mdp.n_actions:
            raise InvalidActionError(f"action {action!r} is outside Discrete({self.mdp.n_actions})")
        self._t += 1
        if not self.mdp.action_mask[self._state, a]:
            if self.invalid_action == "raise":
                s_lab = self.mdp.states[self._state]
                raise InvalidActionError(
                    f"action {self.mdp.actions[a]!r} is not available in state {s_lab!r}; "
                    f"A(s) = {self.mdp.available_actions(s_lab)!r} (see info['action_mask'])"
                )
            reward, terminated = self.invalid_reward, False
        else:
            nxt, reward, terminated = self.mdp.step(self._state, a, self.np_random)
            self._state = nxt
        truncated = (not terminated) and self.max_steps is not None and self._t >= self.max_steps
        return np.int64(self._state), reward, terminated, bool(truncated), self._info()

    def render(self) -> str | None:
        """Text rendering (``render_mode="ansi"``): the grid for grid problems, else the state."""
        if self.render_mode != "ansi":
            return None
        grid = self.mdp.grid
        if grid is None:
            return f"state: {self.mdp.states[self._state]!r}\n"
        rows = []
        for r in range(grid.shape[0]):
            line = ""
            for c in range(grid.shape[1]):
                s = grid.state_at((r, c))
                kind = grid.kinds.get((r, c), "")
                if s is not None and s == self._state:
                    line += "A"
                elif kind == "wall" or s is None:
                    line += "#"
                else:
                    line += {"goal": "G", "mountain": "M", "start": "S", "cliff": "C"}.get(
                        kind, "."
                    )
            rows.append(line)
        return "\n".join(rows) + "\n"


def make_problem_env(problem: str, max_steps: int | None = None, **kwargs: Any) -> MDPEnv:
    """Entry point of the registered ``policylab/<Name>-v0`` ids: a built-in problem's env.

    Args:
        problem: Registered problem name (``recycling-robot``).
        max_steps: Step limit; default: the problem's own (continuing tasks have one).
        **kwargs: Passed to :class:`MDPEnv` (``invalid_action``, ``render_mode``, ...).
    """
    from policylab.problems.registry import problem as get_spec

    spec = get_spec(problem)
    return MDPEnv(spec.builder(), max_steps=max_steps or spec.max_episode_steps, **kwargs)
