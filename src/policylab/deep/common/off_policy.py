"""What the off-policy actor-critics (SAC, TD3) share: continuous actions, replay, the loop.

An :class:`OffPolicyAgent` acts on a bounded ``Box`` action space through a policy whose
actions lie in [-1, 1]^m (a tanh output), rescaled to the space's bounds only at the
env; the replay buffer keeps the [-1, 1] actions. Each iteration collects
``train_freq`` env steps (uniformly random ones for the first ``learning_starts``
steps), then takes ``gradient_steps`` updates of the subclass's :meth:`_train_step`
on minibatches of the buffer. An observation, reward or loss that is NaN or infinite
stops training with a :class:`~policylab.exceptions.NonFiniteError` naming the step and
the value; the run folder keeps its last good checkpoint.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray

from policylab.deep.common.agent import Agent, BaseConfig
from policylab.deep.common.buffers import NStepWindow, ReplayBatch, ReplayBuffer
from policylab.deep.common.checkpoint import to_numpy_tree
from policylab.deep.common.config import check_replay_settings, option
from policylab.deep.common.losses import polyak_update, twin_q_loss, twin_q_loss_grad
from policylab.deep.common.mlp_grad import ChainPasses, as_one_tensor, fused_adam_step
from policylab.deep.common.networks import TwinQNetwork, clip_grad_norm
from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.validation import fmt_number

__all__ = [
    "OffPolicyAgent",
    "OffPolicyConfig",
    "Tensors",
    "check_bounded_box",
    "twin_q_passes",
]

Tensors = dict[str, torch.Tensor]

_ACT_NAMES: dict[type[torch.nn.Module], str] = {
    torch.nn.ReLU: "relu",
    torch.nn.Tanh: "tanh",
    torch.nn.ELU: "elu",
}


def twin_q_passes(critic: TwinQNetwork) -> ChainPasses:
    """The hand-written passes of the twin critics: both MLPs as stacked blocks.

    ``passes.forward(passes.with_ones(s, a))[..., 0]`` is (2, B) Q_1(s, a), Q_2(s, a)
    (``first=1``: Q_1 alone, (1, B)), and ``passes.backward(dq[..., None], ...)``
    backpropagates dL/dQ_i: into the critics' ``.grad``, and with ``input_grad`` the
    action's columns of [s, a] to dL/da = sum_i dz_1,i W_a,i^T.
    """
    return ChainPasses(critic.block_parts(), _ACT_NAMES[type(critic.act)])


@dataclasses.dataclass
class OffPolicyConfig(BaseConfig):
    """Settings of the off-policy actor-critics (Stable-Baselines3's names)."""

    hidden: tuple[int, ...] = option((256, 256), "Hidden layer sizes of the actor and critics.")
    activation: str = option("relu", "Activation of the MLP hidden layers: tanh, relu or elu.")
    buffer_size: int = option(1_000_000, "Replay buffer capacity in transitions.")
    learning_starts: int = option(
        100, "Env steps of uniformly random actions before the first update."
    )
    batch_size: int = option(256, "Minibatch size of each gradient step.")
    tau: float = option(0.005, "Polyak weight of the target networks' update.")
    train_freq: int = option(1, "Env steps (summed over envs) between rounds of gradient steps.")
    gradient_steps: int = option(1, "Gradient steps in each round.")
    max_grad_norm: float = option(
        math.inf, "Clip the global gradient norm of each network to this (inf: no clipping)."
    )

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        super().validate()
        check_replay_settings(self)


def check_bounded_box(algo: str, space: gym.Space[Any]) -> gym.spaces.Box:
    """``space`` if it is a 1-d ``Box`` with finite bounds, else a clear error."""
    if not isinstance(space, gym.spaces.Box) or len(space.shape) != 1:
        raise InvalidArgumentError(
            f"{algo} needs a continuous action space (a 1-d gymnasium.spaces.Box); got {space}"
        )
    if not (np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))):
        raise InvalidArgumentError(
            f"{algo} rescales its tanh actions to the action space's bounds, so they must be "
            f"finite; got low={space.low}, high={space.high}"
        )
    if np.any(space.high <= space.low):
        raise InvalidArgumentError(
            f"{algo} needs high > low in every action dimension; got low={space.low}, "
            f"high={space.high}"
        )
    return space


class OffPolicyAgent(Agent):
    """Base of SAC and TD3: a replay buffer, [-1, 1] actions, and the collect/update loop.

    A subclass builds its actor in :meth:`_build_networks` (the critics with
    :meth:`_build_critics`), picks exploration actions
    in :meth:`_explore`, greedy ones in :meth:`_policy`, and writes one update in
    :meth:`_train_step`.
    """

    config: OffPolicyConfig

    def _build(self) -> None:
        cfg = self.config
        box = check_bounded_box(self.algo.upper(), self.action_space)
        if not isinstance(self.observation_space, gym.spaces.Box):
            raise InvalidArgumentError(
                f"{self.algo.upper()} needs a Box observation space; got {self.observation_space}"
            )
        self.action_dim = int(box.shape[0])
        self.obs_dim = int(np.prod(self.observation_space.shape))
        self._low = box.low.astype(np.float64)
        self._half_range = 0.5 * (box.high.astype(np.float64) - self._low)
        self.replay = ReplayBuffer(
            cfg.buffer_size,
            tuple(self.observation_space.shape),
            np.float32,
            action_shape=(self.action_dim,),
            action_dtype=np.float32,
            seed=self.rng,
        )
        self.window = NStepWindow(cfg.n_envs, 1, cfg.gamma)
        self._build_networks()

    @property
    @abstractmethod
    def metric_names(self) -> tuple[str, ...]:
        """The names of the statistics :meth:`_train_step` reports."""

    @abstractmethod
    def _build_networks(self) -> None:
        """Create the actor, critics, their targets and optimizers."""

    @abstractmethod
    def _policy(self, obs: torch.Tensor) -> torch.Tensor:
        """Greedy actions in [-1, 1] for a batch of prepared observations."""

    @abstractmethod
    def _explore(self, obs: torch.Tensor) -> torch.Tensor:
        """Exploration actions in [-1, 1] for a batch of prepared observations."""

    @abstractmethod
    def _train_step(self, batch: ReplayBatch) -> Tensors:
        """One update on a minibatch; returns its losses and statistics as 0-d tensors."""

    @abstractmethod
    def _network_state(self, training_state: bool) -> dict[str, Any]:
        """The subclass's networks (and optimizers, if ``training_state``)."""

    @abstractmethod
    def _load_network_state(self, tensors: dict[str, Any]) -> None:
        """Restore what :meth:`_network_state` gave."""

    def _build_critics(self) -> None:
        """The twin critics, their target copy and their Adam optimizer."""
        cfg = self.config
        self.critic = TwinQNetwork(
            self.obs_dim, self.action_dim, cfg.hidden, cfg.activation, self.torch_gen
        )
        self.critic_target = copy.deepcopy(self.critic).requires_grad_(False)
        self.critic_target.lay_out_blocks()
        self.critic.lay_out_blocks(grads=True)  # one tensor for the optimizer's step
        self._critic_passes = twin_q_passes(self.critic)
        self._target_passes = twin_q_passes(self.critic_target)
        # the parameter lists the updates pass around, collected once
        self._critic_params = list(self.critic.parameters())
        self._target_params = list(self.critic_target.parameters())
        self._polyak_operands: dict[
            tuple[int, int], tuple[list[torch.Tensor], list[torch.Tensor]]
        ] = {}
        self.critic_optimizer = torch.optim.Adam(
            self._critic_params, lr=cfg.learning_rate, fused=True
        )

    def _polyak_update(
        self, target: Sequence[torch.Tensor], online: Sequence[torch.Tensor]
    ) -> None:
        """The Polyak average theta' <- tau theta + (1 - tau) theta' of a network's target.

        As one tensor each where both are laid out alike as blocks (:func:`as_one_tensor`,
        found again when their memory moved, as in a copy of the agent).
        """
        key = (target[0].data_ptr(), online[0].data_ptr())
        whole = self._polyak_operands.get(key)
        if whole is None:
            whole = self._polyak_operands[key] = as_one_tensor(target, online)
        polyak_update(whole[0], whole[1], self.config.tau)

    @staticmethod
    def _batch_tensors(batch: ReplayBatch) -> tuple[torch.Tensor, ...]:
        """(S, A, R, S', d) of a minibatch as tensors (sharing the sampled arrays)."""
        return tuple(
            torch.as_tensor(x)
            for x in (batch.obs, batch.actions, batch.returns, batch.next_obs, batch.discounts)
        )

    def _critic_step(
        self, obs: torch.Tensor, actions: torch.Tensor, targets: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """One Adam step of the twin critics on their loss toward ``targets``.

        The critics' forward and backward passes are written out by hand
        (:func:`twin_q_passes`), from the loss's own gradient
        (:func:`~policylab.deep.common.losses.twin_q_loss_grad`): no autograd graph.

        Returns:
            The loss and (2, B) Q_1(S, A), Q_2(S, A), both detached.
        """
        passes = self._critic_passes
        q = passes.forward(passes.with_ones(obs, actions))[..., 0]
        loss = twin_q_loss(q, targets)
        passes.backward(twin_q_loss_grad(q, targets).unsqueeze(-1))
        self._clip_grads(self._critic_params)
        fused_adam_step(self.critic_optimizer)
        return loss, q

    # ---------------------------------------------------------------- actions
    def to_env_actions(self, actions: NDArray[Any]) -> NDArray[Any]:
        """[-1, 1] actions rescaled to the action space: low + (a + 1) (high - low) / 2."""
        out: NDArray[Any] = (self._low + (actions + 1.0) * self._half_range).astype(
            self.action_space.dtype
        )
        return out

    def _act(self, obs: torch.Tensor, deterministic: bool) -> NDArray[Any]:
        a = self._policy(obs) if deterministic else self._explore(obs)
        return self.to_env_actions(a.numpy())

    def _clip_grads(self, params: Sequence[torch.Tensor]) -> None:
        if math.isfinite(self.config.max_grad_norm):
            clip_grad_norm(params, self.config.max_grad_norm)

    # ------------------------------------------------------------------ loop
    def _iteration(self) -> dict[str, float]:
        cfg = self.config
        n = self.envs.num_envs
        obs = self._obs
        assert obs is not None
        steps = 0
        while steps < cfg.train_freq:
            x = self._prepare(obs, update=True)
            if self.num_timesteps < cfg.learning_starts:
                actions = self.rng.uniform(-1.0, 1.0, (n, self.action_dim)).astype(np.float32)
            else:
                with torch.no_grad():
                    actions = self._explore(torch.as_tensor(x)).numpy()
            next_obs, rew, term, trunc, valid = self._env_step(self.to_env_actions(actions))
            self._check_finite(next_obs, rew)
            steps += int(valid.sum())  # an autoreset step is no transition
            out = self.window.push(x, actions, rew, self._prepare(next_obs), term, trunc, valid)
            if out is not None:
                self.replay.add(*out)
            obs = next_obs
        # every iteration reports the same metrics (NaN before the first update, or for a
        # loss this iteration did not compute), so progress.csv has all of them as columns
        metrics = dict.fromkeys(self.metric_names, math.nan)
        if self.num_timesteps <= cfg.learning_starts or len(self.replay) < cfg.batch_size:
            return metrics
        stats = [
            self._train_step(self.replay.sample(cfg.batch_size)) for _ in range(cfg.gradient_steps)
        ]
        keys = list(dict.fromkeys(k for s in stats for k in s))
        if not keys:
            return metrics
        # per-key means in one pass (a key missing from a step, such as TD3's delayed
        # actor loss, is averaged over the steps that have it)
        means = [torch.stack([s[k] for s in stats if k in s]).mean() for k in keys]
        computed = dict(zip(keys, torch.stack(means).tolist(), strict=True))
        metrics.update(computed)
        bad = [k for k, v in computed.items() if not math.isfinite(v)]
        if bad:
            raise NonFiniteError(
                f"{self.algo.upper()} {' and '.join(bad)} became NaN or infinite in the update "
                f"after env step {self.num_timesteps:,} (update {self.n_updates:,}); the run "
                "folder keeps its last good checkpoint. Lower learning_rate, set "
                "max_grad_norm, or normalise observations (normalize_obs)."
            )
        return metrics

    def _check_finite(self, obs: NDArray[Any], rewards: NDArray[Any]) -> None:
        for name, value in (("observation", obs), ("reward", rewards)):
            if not np.all(np.isfinite(value)):
                flat = np.asarray(value, dtype=np.float64).reshape(len(value), -1)
                env = int(np.flatnonzero(~np.isfinite(flat).all(axis=1))[0])
                got = value[env]
                shown = fmt_number(got) if np.ndim(got) == 0 else np.array2string(flat[env])
                raise NonFiniteError(
                    f"env {env} returned a non-finite {name} at env step "
                    f"{self.num_timesteps:,}: {shown}; the run folder keeps its last "
                    "good checkpoint"
                )

    # ------------------------------------------------------------ checkpoints
    def _state_tensors(self, training_state: bool) -> dict[str, Any]:
        state = self._network_state(training_state)
        if training_state:
            state["replay"] = self.replay.state_dict()
        return state

    def _load_state_tensors(self, tensors: dict[str, Any]) -> None:
        self._load_network_state(tensors)
        if "replay" in tensors:
            self.replay.load_state_dict(to_numpy_tree(tensors["replay"]))
