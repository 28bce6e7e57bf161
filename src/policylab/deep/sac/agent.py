"""Soft Actor-Critic (Haarnoja et al. 2018) with twin critics and automatic entropy tuning."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import torch

from policylab.deep.common.buffers import ReplayBatch
from policylab.deep.common.config import check, documented, option
from policylab.deep.common.losses import clipped_double_q_targets
from policylab.deep.common.mlp_grad import (
    ChainPasses,
    FlatParameters,
    fused_adam_step,
    match_state_layout,
    mlp_layers,
)
from policylab.deep.common.off_policy import (
    OffPolicyAgent,
    OffPolicyConfig,
    Tensors,
)
from policylab.deep.sac.losses import (
    entropy_coef_loss_grad,
    sac_actor_loss,
    sac_actor_loss_grad,
    squashed_gaussian_grad,
)
from policylab.deep.sac.networks import SquashedGaussianActor
from policylab.exceptions import InvalidArgumentError

__all__ = ["SAC", "SACConfig"]


@documented
@dataclasses.dataclass
class SACConfig(OffPolicyConfig):
    """Hyperparameters of :class:`SAC` (the same names in config files and the CLI)."""

    ent_coef: float | str = option(
        "auto",
        "Entropy temperature alpha: a number, or 'auto' ('auto_0.1': starting at 0.1) to "
        "learn it toward target_entropy.",
    )
    target_entropy: float | str = option(
        "auto", "Entropy the learned alpha aims at ('auto': minus the action dimension)."
    )
    target_update_interval: int = option(
        1, "Gradient steps between Polyak updates of the target critics."
    )

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        super().validate()
        _initial_alpha(self.ent_coef)
        if isinstance(self.target_entropy, str):
            check(
                self.target_entropy == "auto",
                f"target_entropy must be a number or 'auto'; got {self.target_entropy!r}",
            )
        check(self.target_update_interval >= 1, "target_update_interval must be >= 1")


def _initial_alpha(ent_coef: float | str) -> tuple[float, bool]:
    """(alpha at the start, whether it is learned) of an ``ent_coef`` setting."""
    if isinstance(ent_coef, str):
        if ent_coef == "auto":
            return 1.0, True
        if ent_coef.startswith("auto_"):
            try:
                value = float(ent_coef[5:])
            except ValueError:
                value = -1.0
            if value > 0:
                return value, True
        raise InvalidArgumentError(
            f"ent_coef must be a number > 0, 'auto' or 'auto_<start value>'; got {ent_coef!r}"
        )
    if not ent_coef > 0 or not math.isfinite(ent_coef):
        raise InvalidArgumentError(f"ent_coef must be > 0; got {ent_coef!r}")
    return float(ent_coef), False


class SAC(OffPolicyAgent):
    """SAC: a squashed Gaussian policy, twin soft Q critics, and a learned temperature.

    Each gradient step on a minibatch (S, A, R, S', d) of the replay buffer:

    1. critics: one Adam step on sum_i E[(Q_i(S, A) - y)^2] / 2 with the soft target
       y = R + d (min_i Q'_i(S', A') - alpha log pi(A' | S')), A' ~ pi(. | S');
    2. actor: one step on E[alpha log pi(a | S) - min_i Q_i(S, a)], a ~ pi(. | S) (the
       critics' weights held constant, so their gradients are never computed);
    3. alpha, when ``ent_coef`` is learned: one step on J(alpha)
       (:func:`~policylab.deep.sac.losses.entropy_coef_loss`) with the same a;
    4. every ``target_update_interval`` steps, Q' <- tau Q + (1 - tau) Q'.

    Both losses use alpha from before this step, as in Stable-Baselines3, so the order
    of the alpha step does not change the result.

    The update builds no autograd graph: the actor's MLP is backpropagated by
    :class:`~policylab.deep.common.mlp_grad.ChainPasses`, the critics by the same
    passes on their stacked blocks, and each loss has its
    gradient written next to it (``twin_q_loss_grad``, ``sac_actor_loss_grad``,
    ``squashed_gaussian_grad``, ``entropy_coef_loss_grad``); the parameters after an
    update equal those of the same update through autograd, to float rounding. The
    policy runs at S and S' as one batch of 2B rows.

    Actions are tanh outputs rescaled to the bounds of the env's ``Box`` action space.

    Example:
        >>> import policylab as pl
        >>> agent = pl.deep.SAC("Pendulum-v1", learning_rate=1e-3)  # doctest: +SKIP
        >>> agent.learn(20_000)                                     # doctest: +SKIP
    """

    algo = "sac"
    config_class = SACConfig
    config: SACConfig

    def _build_networks(self) -> None:
        cfg = self.config
        g = self.torch_gen
        self.actor = SquashedGaussianActor(
            self.obs_dim, self.action_dim, cfg.hidden, cfg.activation, g
        )
        self._build_critics()
        layers = mlp_layers(self.actor.net)
        assert layers is not None  # an ActorMLP is a plain MLP
        # each layer as one [W^T; b] block (ChainPasses); the actor's optimizer keeps one
        # tensor per parameter (views of the blocks), as autograd and checkpoints see them
        FlatParameters.of_chain(layers)
        self._actor_passes = ChainPasses(layers, cfg.activation)
        self._actor_params = list(self.actor.parameters())
        lr = cfg.learning_rate
        alpha0, self.learn_alpha = _initial_alpha(cfg.ent_coef)
        self.log_alpha = torch.tensor(math.log(alpha0), requires_grad=self.learn_alpha)
        # log alpha steps with the actor, in one Adam (Adam treats each tensor on its own,
        # so this is two separate Adam updates in one call)
        groups: list[dict[str, Any]] = [{"params": self._actor_params}]
        if self.learn_alpha:
            groups.append({"params": [self.log_alpha]})
        self.actor_optimizer = torch.optim.Adam(groups, lr=lr, fused=True)
        te = cfg.target_entropy
        self.target_entropy = -float(self.action_dim) if te == "auto" else float(te)

    @property
    def metric_names(self) -> tuple[str, ...]:
        """The statistics of each update (``ent_coef_loss`` when alpha is learned)."""
        names = ("critic_loss", "actor_loss", "q_mean", "ent_coef", "entropy")
        return (*names, "ent_coef_loss") if self.learn_alpha else names

    @property
    def alpha(self) -> float:
        """The entropy temperature now."""
        return float(self.log_alpha.detach().exp())

    def _policy(self, obs: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.actor(obs)
        return out

    def _explore(self, obs: torch.Tensor) -> torch.Tensor:
        return self.actor.sample(obs, self.torch_gen, log_prob=False)[0]

    def _train_step(self, batch: ReplayBatch) -> Tensors:
        cfg = self.config
        obs, actions, rewards, next_obs, discounts = self._batch_tensors(batch)
        b = len(obs)
        stats: Tensors = {}
        alpha = self.log_alpha.detach().exp()  # alpha before this step

        # Every network's forward and backward pass is written out (ChainPasses, for the
        # critics on their stacked blocks) and every loss's gradient is its own tested
        # function: no autograd graph. The policy at S and S' in one pass.
        actor, critic, target = self._actor_passes, self._critic_passes, self._target_passes
        features = actor.forward(actor.with_ones(torch.cat([obs, next_obs])))
        all_actions, all_log_prob, noise, in_range = self.actor.reparameterised(
            features, self.torch_gen
        )
        actions_pi, log_prob = all_actions[:b], all_log_prob[:b]

        # 1. the critics, toward the soft clipped double-Q target
        next_q = target.forward(target.with_ones(next_obs, all_actions[b:]), keep=False)[..., 0]
        y = clipped_double_q_targets(rewards, discounts, next_q, all_log_prob[b:], alpha)
        critic_loss, q = self._critic_step(obs, actions, y)

        # 2. the actor, through the updated critics with their weights held constant:
        # dJ/dQ, then dJ/da = dJ/dQ dQ/da through the critics, then through the squash
        q_pi = critic.forward(critic.with_ones(obs, actions_pi))[..., 0]
        actor_loss = sac_actor_loss(log_prob, q_pi, alpha)
        grad_log_prob, grad_q = sac_actor_loss_grad(log_prob, q_pi, alpha)
        grad_action = critic.backward(
            grad_q.unsqueeze(-1), param_grads=False, input_grad=slice(self.obs_dim, -1)
        )
        assert grad_action is not None
        grad_mean, grad_log_std = squashed_gaussian_grad(
            actions_pi, noise[:b], grad_action, grad_log_prob
        )
        grad_features = torch.cat([grad_mean, grad_log_std * in_range[:b]], 1)
        actor.backward(grad_features, rows=b)
        if self.learn_alpha:
            # 3. alpha (its loss reaches log alpha only: log pi is held constant in it)
            grad_log_alpha = entropy_coef_loss_grad(log_prob, self.target_entropy)
            # J(alpha) is linear in log alpha: J = log alpha * dJ/dlog alpha
            stats["ent_coef_loss"] = self.log_alpha.detach() * grad_log_alpha
            self.log_alpha.grad = grad_log_alpha
        self._clip_grads(self._actor_params)
        fused_adam_step(self.actor_optimizer)

        # 4. the target critics
        self.n_updates += 1
        if self.n_updates % cfg.target_update_interval == 0:
            self._polyak_update(self._target_params, self._critic_params)
        stats.update(
            critic_loss=critic_loss,
            actor_loss=actor_loss,
            q_mean=q.mean(),
            ent_coef=alpha,
            entropy=-log_prob.mean(),
        )
        return stats

    def _network_state(self, training_state: bool) -> dict[str, Any]:
        state: dict[str, Any] = {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "critic_target": self.critic_target.state_dict(),
            "ent_coef": {"log_alpha": self.log_alpha.detach().clone()},
        }
        if training_state:
            state["actor_optimizer"] = self.actor_optimizer.state_dict()
            state["critic_optimizer"] = self.critic_optimizer.state_dict()
        return state

    def _load_network_state(self, tensors: dict[str, Any]) -> None:
        self.actor.load_state_dict(tensors["actor"])
        self.critic.load_state_dict(tensors["critic"])
        self.critic_target.load_state_dict(tensors["critic_target"])
        with torch.no_grad():
            self.log_alpha.copy_(tensors["ent_coef"]["log_alpha"])
        if "actor_optimizer" in tensors:
            self.actor_optimizer.load_state_dict(tensors["actor_optimizer"])
            self.critic_optimizer.load_state_dict(tensors["critic_optimizer"])
            for optimizer in (self.actor_optimizer, self.critic_optimizer):
                match_state_layout(optimizer)  # moments laid out as the [W^T; b] blocks
