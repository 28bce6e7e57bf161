"""PPO's actor-critic: a categorical or diagonal Gaussian policy and a value function."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from policylab.deep.common.networks import build_torso, init_layer, is_image_space, torso_width
from policylab.exceptions import InvalidArgumentError

__all__ = ["ActorCritic"]

_LOG_2PI = math.log(2 * math.pi)


class ActorCritic(nn.Module):
    """pi(a | s) and V(s). Vector observations get two separate MLPs; images share one CNN.

    Args:
        observation_space: The env's single observation space.
        action_space: Discrete (categorical policy) or Box (diagonal Gaussian policy with
            a state-independent learned log std).
        hidden: MLP hidden sizes.
        act: MLP activation.
        log_std_init: Initial log standard deviation of a Gaussian policy.
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        observation_space: gym.Space[Any],
        action_space: gym.Space[Any],
        hidden: tuple[int, ...],
        act: str,
        log_std_init: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        if isinstance(action_space, gym.spaces.Discrete):
            self.continuous = False
            out = int(action_space.n)
        elif isinstance(action_space, gym.spaces.Box) and len(action_space.shape) == 1:
            self.continuous = True
            out = int(action_space.shape[0])
        else:
            raise InvalidArgumentError(
                f"PPO needs a Discrete or a 1-d Box action space; got {action_space}"
            )
        self.shared = is_image_space(observation_space)
        self.actor_torso = build_torso(observation_space, hidden, act, generator)
        self.critic_torso = (
            self.actor_torso
            if self.shared
            else build_torso(observation_space, hidden, act, generator)
        )
        w = torso_width(self.actor_torso)
        self.policy_head = init_layer(nn.Linear(w, out), 0.01, generator)
        self.value_head = init_layer(nn.Linear(w, 1), 1.0, generator)
        self.log_std = (
            nn.Parameter(torch.full((out,), float(log_std_init))) if self.continuous else None
        )

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """V(s) for a batch, shape (B,)."""
        v: torch.Tensor = self.value_head(self.critic_torso(obs)).squeeze(-1)
        return v

    def _policy_out(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self.shared:
            h = self.actor_torso(obs)
            return self.policy_head(h), self.value_head(h).squeeze(-1)
        return self.policy_head(self.actor_torso(obs)), self.value(obs)

    def _log_prob_entropy(
        self, out: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        if self.continuous:
            assert self.log_std is not None
            log_std = self.log_std.expand_as(out)
            z = (actions - out) / log_std.exp()
            logp = (-0.5 * z**2 - log_std - 0.5 * _LOG_2PI).sum(-1)
            ent = (0.5 + 0.5 * _LOG_2PI + log_std).sum(-1)
            return logp, ent
        logits = torch.log_softmax(out, dim=-1)
        logp = logits.gather(-1, actions.long().unsqueeze(-1)).squeeze(-1)
        ent = -(logits.exp() * logits).sum(-1)
        return logp, ent

    def sample(
        self, obs: torch.Tensor, generator: torch.Generator | None, deterministic: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Actions drawn from pi(. | s) (or its mode), their log-probabilities, and V(s)."""
        out, v = self._policy_out(obs)
        if self.continuous:
            assert self.log_std is not None
            if deterministic:
                a = out
            else:
                a = out + self.log_std.exp() * torch.randn(out.shape, generator=generator)
        elif deterministic:
            a = out.argmax(-1)
        else:
            a = torch.multinomial(torch.softmax(out, -1), 1, generator=generator).squeeze(-1)
        logp, _ = self._log_prob_entropy(out, a)
        return a, logp, v

    def evaluate_actions(
        self, obs: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Log pi(a | s), the policy's entropy at s, and V(s), for a batch."""
        out, v = self._policy_out(obs)
        logp, ent = self._log_prob_entropy(out, actions)
        return logp, ent, v


def action_dtype(space: gym.Space[Any]) -> Any:
    """NumPy dtype of stored actions."""
    return np.float32 if isinstance(space, gym.spaces.Box) else np.int64
