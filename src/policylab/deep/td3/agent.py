"""Twin Delayed DDPG (Fujimoto et al. 2018): clipped double Q, target smoothing, delayed actor."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import torch

from policylab.deep.common.buffers import ReplayBatch
from policylab.deep.common.config import check, documented, option
from policylab.deep.common.losses import clipped_double_q_targets
from policylab.deep.common.mlp_grad import (
    ChainPasses,
    FlatParameters,
    activation_backward,
    fused_adam_step,
    match_state_layout,
    mlp_layers,
)
from policylab.deep.common.off_policy import (
    OffPolicyAgent,
    OffPolicyConfig,
    Tensors,
)
from policylab.deep.td3.losses import smoothed_target_actions, td3_actor_loss, td3_actor_loss_grad
from policylab.deep.td3.networks import DeterministicActor

__all__ = ["TD3", "TD3Config"]


@documented
@dataclasses.dataclass
class TD3Config(OffPolicyConfig):
    """Hyperparameters of :class:`TD3` (the same names in config files and the CLI)."""

    learning_rate: float = option(1e-3, "Adam step size of the actor and the critics.")
    hidden: tuple[int, ...] = option(
        (400, 300), "Hidden layer sizes of the actor and critics (those of Fujimoto et al.)."
    )
    policy_delay: int = option(2, "Critic updates per actor (and target network) update.")
    target_policy_noise: float = option(
        0.2, "Std of the Gaussian noise on the target actor's actions (target smoothing)."
    )
    target_noise_clip: float = option(0.5, "The target smoothing noise is clipped to +-this.")
    action_noise: float = option(
        0.1, "Std of the Gaussian exploration noise on actions in [-1, 1] (0: none)."
    )

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        super().validate()
        check(self.policy_delay >= 1, f"policy_delay must be >= 1; got {self.policy_delay}")
        for name in ("target_policy_noise", "target_noise_clip", "action_noise"):
            v = getattr(self, name)
            check(v >= 0, f"{name} must be >= 0; got {v}")


class TD3(OffPolicyAgent):
    """TD3: a deterministic actor, twin critics, and three fixes of DDPG's overestimation.

    Each gradient step on a minibatch (S, A, R, S', d) of the replay buffer:

    1. critics: one Adam step on sum_i E[(Q_i(S, A) - y)^2] / 2 with the clipped
       double-Q target y = R + d min_i Q'_i(S', A') and the smoothed target action
       A' = clip(mu'(S') + clip(eps, -c, c), -1, 1), eps ~ N(0, target_policy_noise^2);
    2. every ``policy_delay`` steps, the actor: one step on -E[Q_1(S, mu(S))] (the
       critic's weights held constant, so their gradients are never computed), then
       Polyak updates of the target actor and critics.

    Each update builds no autograd graph: the actors' MLPs go through
    :class:`~policylab.deep.common.mlp_grad.ChainPasses`, the critics through the
    same passes on their stacked blocks, from the losses'
    gradients (``twin_q_loss_grad``, ``td3_actor_loss_grad``); the parameters after an
    update equal those of the same update through autograd, to float rounding.

    Exploration adds N(0, action_noise^2) to mu(s) (clipped to [-1, 1]); actions are
    rescaled to the bounds of the env's ``Box`` action space.

    Example:
        >>> import policylab as pl
        >>> agent = pl.deep.TD3("Pendulum-v1", gamma=0.98)  # doctest: +SKIP
        >>> agent.learn(20_000)                             # doctest: +SKIP
    """

    algo = "td3"
    config_class = TD3Config
    config: TD3Config

    def _build_networks(self) -> None:
        cfg = self.config
        g = self.torch_gen
        self.actor = DeterministicActor(
            self.obs_dim, self.action_dim, cfg.hidden, cfg.activation, g
        )
        self.actor_target = copy.deepcopy(self.actor).requires_grad_(False)
        self._build_critics()
        layers, target_layers = mlp_layers(self.actor.net), mlp_layers(self.actor_target.net)
        assert layers is not None and target_layers is not None  # ActorMLPs are plain MLPs
        # each layer as one [W^T; b] block (ChainPasses); the actor's optimizer keeps one
        # tensor per parameter (views of the blocks), as autograd and checkpoints see them
        for chain in (layers, target_layers):
            FlatParameters.of_chain(chain)
        self._actor_passes = ChainPasses(layers, cfg.activation)
        self._target_actor_passes = ChainPasses(target_layers, cfg.activation)
        self._actor_params = list(self.actor.parameters())
        self._actor_target_params = list(self.actor_target.parameters())
        self.actor_optimizer = torch.optim.Adam(
            self._actor_params, lr=cfg.learning_rate, fused=True
        )

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The statistics of each update (``actor_loss`` every ``policy_delay`` updates)."""
        return ("critic_loss", "q_mean", "actor_loss")

    def _policy(self, obs: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.actor(obs)
        return out

    def _explore(self, obs: torch.Tensor) -> torch.Tensor:
        a = self.actor(obs)
        sigma = self.config.action_noise
        if sigma > 0:
            a = (a + sigma * torch.randn(a.shape, generator=self.torch_gen)).clamp(-1.0, 1.0)
        out: torch.Tensor = a
        return out

    def _train_step(self, batch: ReplayBatch) -> Tensors:
        cfg = self.config
        obs, actions, rewards, next_obs, discounts = self._batch_tensors(batch)
        actor, target_actor = self._actor_passes, self._target_actor_passes
        critic, target = self._critic_passes, self._target_passes

        # Every forward and backward pass is written out, as in SAC (no autograd graph).
        # 1. the critics, toward the clipped double-Q target of the smoothed target action
        noise = cfg.target_policy_noise * torch.randn(actions.shape, generator=self.torch_gen)
        target_mu = torch.tanh(target_actor.forward(target_actor.with_ones(next_obs), keep=False))
        next_actions = smoothed_target_actions(target_mu, noise, cfg.target_noise_clip)
        y = clipped_double_q_targets(
            rewards,
            discounts,
            target.forward(target.with_ones(next_obs, next_actions), keep=False)[..., 0],
        )
        critic_loss, q = self._critic_step(obs, actions, y)
        self.n_updates += 1
        stats: Tensors = {"critic_loss": critic_loss, "q_mean": q.mean()}

        # 2. delayed: the actor through Q_1 with the critic's weights constant, then targets
        if self.n_updates % cfg.policy_delay == 0:
            mu = torch.tanh(actor.forward(actor.with_ones(obs)))
            q1 = critic.forward(critic.with_ones(obs, mu), first=1)[..., 0]
            grad_mu = critic.backward(
                td3_actor_loss_grad(q1).unsqueeze(-1),
                param_grads=False,
                input_grad=slice(self.obs_dim, -1),
            )
            assert grad_mu is not None
            grad_features = activation_backward(grad_mu, mu, "tanh")
            actor.backward(grad_features)
            self._clip_grads(self._actor_params)
            fused_adam_step(self.actor_optimizer)
            self._polyak_update(self._actor_target_params, self._actor_params)
            self._polyak_update(self._target_params, self._critic_params)
            stats["actor_loss"] = td3_actor_loss(q1[0])
        return stats

    def _network_state(self, training_state: bool) -> dict[str, Any]:
        state: dict[str, Any] = {
            "actor": self.actor.state_dict(),
            "actor_target": self.actor_target.state_dict(),
            "critic": self.critic.state_dict(),
            "critic_target": self.critic_target.state_dict(),
        }
        if training_state:
            state["actor_optimizer"] = self.actor_optimizer.state_dict()
            state["critic_optimizer"] = self.critic_optimizer.state_dict()
        return state

    def _load_network_state(self, tensors: dict[str, Any]) -> None:
        self.actor.load_state_dict(tensors["actor"])
        self.actor_target.load_state_dict(tensors["actor_target"])
        self.critic.load_state_dict(tensors["critic"])
        self.critic_target.load_state_dict(tensors["critic_target"])
        if "actor_optimizer" in tensors:
            self.actor_optimizer.load_state_dict(tensors["actor_optimizer"])
            self.critic_optimizer.load_state_dict(tensors["critic_optimizer"])
            for optimizer in (self.actor_optimizer, self.critic_optimizer):
                match_state_layout(optimizer)  # moments laid out as the [W^T; b] blocks
