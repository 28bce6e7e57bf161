"""DQN's Q-network: Q(s, .) from an MLP or the Nature CNN, with an optional dueling head."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch
from torch import nn

from policylab.deep.common.mlp_grad import ChainPasses, mlp_layers
from policylab.deep.common.networks import MLP, build_torso, torso_width
from policylab.exceptions import InvalidArgumentError

__all__ = ["QNetwork"]


class QNetwork(nn.Module):
    """Q(s, a) for every action a.

    With ``dueling`` (Wang et al. 2016) the head splits into a state value and
    advantages: Q(s, a) = V(s) + A(s, a) - mean_b A(s, b).

    Args:
        observation_space: The env's single observation space.
        action_space: A Discrete space.
        hidden: MLP hidden sizes (vector observations).
        act: MLP activation.
        dueling: Use the dueling head.
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        observation_space: gym.Space[Any],
        action_space: gym.Space[Any],
        hidden: tuple[int, ...],
        act: str,
        dueling: bool = False,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        if not isinstance(action_space, gym.spaces.Discrete):
            raise InvalidArgumentError(f"DQN needs a Discrete action space; got {action_space}")
        n = int(action_space.n)
        self.torso = build_torso(observation_space, hidden, act, generator)
        w = torso_width(self.torso)
        self.dueling = dueling
        if dueling:
            self.value = MLP(w, (), 1, generator=generator)
            self.advantage = MLP(w, (), n, generator=generator)
        else:
            self.head = MLP(w, (), n, generator=generator)
        self.act = act
        self.chain = None if dueling else mlp_layers(self.torso, self.head)
        """The Linear layers of a plain MLP Q-network (backpropagated by hand), else None."""
        self.passes = None if self.chain is None else ChainPasses(self.chain, act)
        """The forward pass of a plain MLP without autograd, else None."""

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Q(s, .) for a batch, shape (B, A).

        Under ``torch.no_grad`` or ``torch.inference_mode`` a plain MLP runs by
        :class:`~policylab.deep.common.mlp_grad.ChainPasses` (the same numbers to float
        rounding, without the modules' call overhead).
        """
        if self.passes is not None and not torch.is_grad_enabled():
            return self.passes.forward(self.passes.with_ones(obs), keep=False)
        h = self.torso(obs)
        if self.dueling:
            adv = self.advantage(h)
            q: torch.Tensor = self.value(h) + adv - adv.mean(dim=1, keepdim=True)
            return q
        out: torch.Tensor = self.head(h)
        return out
