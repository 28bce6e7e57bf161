"""PPO's actor-critic: a categorical or diagonal Gaussian policy and a value function."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from policylab.deep.common.mlp_grad import ChainPasses, NumpyMLP, mlp_layers
from policylab.deep.common.networks import build_torso, init_layer, is_image_space, torso_width
from policylab.exceptions import InvalidArgumentError

__all__ = ["ActorCritic"]

_LOG_2PI = math.log(2 * math.pi)

Cache = tuple[torch.Tensor, ...]
"""What :meth:`ActorCritic.forward_cached` keeps for :meth:`ActorCritic.backward_cached`
(with what the two MLPs' :class:`~policylab.deep.common.mlp_grad.ChainPasses` keep)."""


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
        self.act = act
        # plain MLPs (vector observations) are backpropagated by hand: see by_hand
        actor = None if self.shared else mlp_layers(self.actor_torso, self.policy_head)
        critic = None if self.shared else mlp_layers(self.critic_torso, self.value_head)
        self.chains = None if actor is None or critic is None else (actor, critic)
        """The Linear layers of the actor's and the critic's MLPs (by hand), else None."""
        self._passes = (
            None
            if self.chains is None
            else (ChainPasses(self.chains[0], act), ChainPasses(self.chains[1], act))
        )
        self._numpy = (
            None
            if self.chains is None
            else (NumpyMLP(self.chains[0], act), NumpyMLP(self.chains[1], act))
        )

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """V(s) for a batch, shape (B,)."""
        if self._passes is not None and not torch.is_grad_enabled():
            critic = self._passes[1]
            return critic.forward(critic.with_ones(obs), keep=False).squeeze(-1)
        v: torch.Tensor = self.value_head(self.critic_torso(obs)).squeeze(-1)
        return v

    def _policy_out(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self._passes is not None and not torch.is_grad_enabled():
            actor, critic = self._passes
            x = actor.with_ones(obs)
            return actor.forward(x, keep=False), critic.forward(x, keep=False).squeeze(-1)
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
        """Actions drawn from pi(. | s) (or its mode), their log-probabilities, and V(s).

        Under ``torch.no_grad`` or ``torch.inference_mode`` two MLPs run by
        :class:`~policylab.deep.common.mlp_grad.ChainPasses`, the forward pass of the
        hand-written update (the same numbers to float rounding, without the modules'
        call overhead).
        """
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

    def sample_numpy(
        self, obs: NDArray[Any], rng: np.random.Generator, deterministic: bool = False
    ) -> tuple[NDArray[Any], NDArray[np.float32], NDArray[np.float32]]:
        """:meth:`sample` computed in NumPy, drawing from ``rng``, for :attr:`by_hand` networks.

        For the few observations of an acting step (one per env) torch's per-operation
        dispatch costs more than the arithmetic; both MLPs run as
        :class:`~policylab.deep.common.mlp_grad.NumpyMLP`. A categorical policy draws
        A ~ softmax(o) by inverting its cumulative distribution at one uniform draw per
        observation, with log pi(a | s) = o_a - logsumexp(o); a Gaussian one draws
        A = mu + sigma z, z ~ N(0, I), with log pi(a | s) = sum_i (-z_i^2 / 2 - log sigma_i
        - log(2 pi) / 2).

        Returns:
            (actions, log-probabilities, V(s)) as NumPy arrays.
        """
        assert self._numpy is not None
        actor, critic = self._numpy
        x = np.asarray(obs, dtype=np.float32)
        out, v = actor(x), critic(x)[:, 0]
        if self.continuous:
            assert self.log_std is not None
            log_std = self.log_std.detach().numpy()
            z = np.zeros_like(out) if deterministic else rng.standard_normal(out.shape, np.float32)
            logp = (-0.5 * z * z - log_std - 0.5 * _LOG_2PI).sum(-1, dtype=np.float32)
            return out + np.exp(log_std) * z, logp, v
        m = out.max(-1, keepdims=True)
        log_pi = out - (m + np.log(np.exp(out - m).sum(-1, keepdims=True)))
        if deterministic:
            a = out.argmax(-1)
        else:
            cdf = np.cumsum(np.exp(log_pi), -1)
            u = rng.random(len(out), dtype=np.float32) * cdf[:, -1]
            a = np.minimum((cdf <= u[:, None]).sum(-1), out.shape[1] - 1)
        return a, np.take_along_axis(log_pi, a[:, None], -1)[:, 0], v

    def evaluate_actions(
        self, obs: torch.Tensor, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Log pi(a | s), the policy's entropy at s, and V(s), for a batch."""
        out, v = self._policy_out(obs)
        logp, ent = self._log_prob_entropy(out, actions)
        return logp, ent, v

    @property
    def by_hand(self) -> bool:
        """Whether :meth:`forward_cached` and :meth:`backward_cached` apply (two MLPs)."""
        return self.chains is not None

    def forward_cached(
        self, obs: torch.Tensor, actions: torch.Tensor, ones: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, Cache]:
        """:meth:`evaluate_actions` without autograd, keeping what the backward pass needs.

        Returns ``(log_prob, entropy, value, cache)``; pass ``cache`` to
        :meth:`backward_cached` (before the next call: the MLPs' passes keep their
        layers' outputs until then). Only for networks with :attr:`by_hand`. With
        ``ones`` the observations come flattened with a column of ones, [s, 1]
        (:meth:`~policylab.deep.common.mlp_grad.ChainPasses.with_ones`).
        """
        assert self._passes is not None
        actor, critic = self._passes
        x = obs if ones else actor.with_ones(obs)
        out, v = actor.forward(x), critic.forward(x)
        with torch.no_grad():
            if self.continuous:
                assert self.log_std is not None
                std = self.log_std.exp()
                z = (actions - out) / std
                logp = (-0.5 * z * z - self.log_std - 0.5 * _LOG_2PI).sum(-1)
                ent = (0.5 + 0.5 * _LOG_2PI + self.log_std).sum().expand(len(out))
                extra: tuple[torch.Tensor, ...] = (z, std)
            else:
                log_pi = torch.log_softmax(out, dim=-1)
                pi = log_pi.exp()
                idx = actions.long().unsqueeze(-1)
                logp = log_pi.gather(-1, idx).squeeze(-1)
                ent = -(pi * log_pi).sum(-1)
                extra = (idx, pi, log_pi, ent)
        return logp, ent, v.squeeze(-1), extra

    def backward_cached(
        self,
        cache: Cache,
        grad_log_prob: torch.Tensor,
        grad_entropy: float,
        grad_value: torch.Tensor,
    ) -> None:
        """Set every parameter's ``.grad`` to dL/dtheta, by the chain rule through both MLPs.

        L depends on the network through log pi(A_t | S_t), the entropy H_t and V(S_t):
        ``grad_log_prob`` is (B,) dL/dlog pi(A_t | S_t), ``grad_entropy`` the dL/dH_t
        shared by all t (-ent_coef / B), ``grad_value`` (B,) dL/dV(S_t). With o the
        policy head's output,

        categorical, p = softmax(o):  dlog p_a/do = onehot(a) - p,  dH/do = -p (log p + H)
        Gaussian, z = (a - mu) / sigma:  dlog pi/dmu = z / sigma,
            dlog pi/dlog sigma = z^2 - 1,  dH/dlog sigma = 1 (per dimension).
        """
        assert self._passes is not None
        actor, critic = self._passes
        with torch.no_grad():
            g = grad_log_prob.unsqueeze(-1)
            if self.continuous:
                assert self.log_std is not None
                z, std = cache
                g_out = g * z / std
                g_log_std = (g * (z * z - 1.0)).sum(0) + grad_entropy * len(z)
                if self.log_std.grad is None:
                    self.log_std.grad = g_log_std
                else:
                    self.log_std.grad.copy_(g_log_std)
            else:
                idx, pi, log_pi, ent = cache
                g_out = pi * ((log_pi + ent.unsqueeze(-1)) * -grad_entropy - g)
                g_out.scatter_add_(-1, idx, g)
            actor.backward(g_out)
            critic.backward(grad_value.unsqueeze(-1))


def action_dtype(space: gym.Space[Any]) -> Any:
    """NumPy dtype of stored actions."""
    return np.float32 if isinstance(space, gym.spaces.Box) else np.int64
