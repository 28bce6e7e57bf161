"""Proximal Policy Optimization (Schulman et al. 2017) for discrete and continuous actions."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray

from policylab.deep.common.agent import Agent, BaseConfig
from policylab.deep.common.buffers import RolloutBuffer
from policylab.deep.common.config import check, documented, option
from policylab.deep.common.mlp_grad import ChainPasses, FlatParameters, fused_adam_step
from policylab.deep.common.networks import clip_grad_norm
from policylab.deep.common.normalize import RewardScaler
from policylab.deep.ppo.losses import (
    approx_kl,
    clipped_surrogate_loss,
    clipped_surrogate_loss_grad,
    normalized,
    value_loss,
    value_loss_grad,
)
from policylab.deep.ppo.networks import ActorCritic, action_dtype

__all__ = ["PPO", "PPOConfig"]


@documented
@dataclasses.dataclass
class PPOConfig(BaseConfig):
    """Hyperparameters of :class:`PPO` (the same names in config files and the CLI)."""

    n_steps: int = option(
        128, "Steps per env in each rollout (a rollout has n_steps * n_envs steps)."
    )
    batch_size: int = option(64, "Minibatch size of the gradient steps.")
    n_epochs: int = option(10, "Passes over each rollout.")
    gae_lambda: float = option(0.95, "lambda of the generalised advantage estimate.")
    clip_range: float = option(
        0.2, "epsilon of the clipped objective: ratios outside [1-eps, 1+eps] give no gradient."
    )
    clip_range_vf: float = option(
        0.0, "Value clipping range around the old values (0: no value clipping)."
    )
    ent_coef: float = option(0.0, "Weight of the entropy bonus.")
    vf_coef: float = option(0.5, "Weight of the value loss.")
    normalize_advantage: bool = option(True, "Normalise advantages within each minibatch.")
    anneal_lr: bool = option(True, "Decay the learning rate linearly to 0 over the run.")
    target_kl: float = option(
        0.0, "Stop a rollout's epochs early once the approximate KL exceeds this (0: never)."
    )
    log_std_init: float = option(
        0.0, "Initial log std of the Gaussian policy (continuous actions)."
    )
    normalize_reward: bool = option(
        False, "Divide rewards by the running std of the discounted return."
    )
    max_grad_norm: float = option(0.5, "Clip the global gradient norm to this value.")

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        super().validate()
        check(self.n_steps >= 1, f"n_steps must be >= 1; got {self.n_steps}")
        check(self.batch_size >= 1, f"batch_size must be >= 1; got {self.batch_size}")
        check(self.n_epochs >= 1, f"n_epochs must be >= 1; got {self.n_epochs}")
        check(0.0 <= self.gae_lambda <= 1.0, f"gae_lambda must be in [0, 1]; got {self.gae_lambda}")
        check(self.clip_range > 0, f"clip_range must be > 0; got {self.clip_range}")
        check(self.clip_range_vf >= 0, f"clip_range_vf must be >= 0; got {self.clip_range_vf}")
        check(self.ent_coef >= 0 and self.vf_coef >= 0, "ent_coef and vf_coef must be >= 0")
        check(self.target_kl >= 0, f"target_kl must be >= 0; got {self.target_kl}")


class PPO(Agent):
    """PPO with a clipped objective, GAE, optional value clipping and an entropy bonus.

    Each iteration collects ``n_steps`` steps of each of the ``n_envs`` envs with the
    current policy, computes GAE advantages (bootstrapping truncated episodes from the
    value of their last state, and never terminated ones), and takes ``n_epochs``
    passes of minibatch Adam steps on

        L = L^CLIP + vf_coef L^V - ent_coef H[pi].

    Example:
        >>> import policylab as pl
        >>> agent = pl.deep.PPO("CartPole-v1", n_envs=8, n_steps=32)  # doctest: +SKIP
        >>> agent.learn(100_000)                                      # doctest: +SKIP
    """

    algo = "ppo"
    config_class = PPOConfig
    config: PPOConfig

    def _build(self) -> None:
        cfg = self.config
        self.net = ActorCritic(
            self.observation_space,
            self.action_space,
            cfg.hidden,
            cfg.activation,
            cfg.log_std_init,
            self.torch_gen,
        )
        # the hand-written update keeps all parameters (and gradients) in one flat
        # tensor, each layer of the two MLPs as one [W^T; b] block (see ChainPasses)
        chains = self.net.chains
        self._flat = (
            None
            if chains is None
            else FlatParameters(list(self.net.parameters()), [*chains[0], *chains[1]])
        )
        self._params = [self._flat.flat] if self._flat is not None else list(self.net.parameters())
        self.optimizer = torch.optim.Adam(self._params, lr=cfg.learning_rate, eps=1e-5, fused=True)
        self.buffer = RolloutBuffer(
            cfg.n_steps,
            cfg.n_envs,
            tuple(self.observation_space.shape or ()),
            tuple(self.action_space.shape or ()),
            obs_dtype=np.uint8 if self.observation_space.dtype == np.uint8 else np.float32,
            action_dtype=action_dtype(self.action_space),
        )
        self.reward_scaler = RewardScaler(cfg.n_envs, cfg.gamma) if cfg.normalize_reward else None

    def _act(self, obs: torch.Tensor, deterministic: bool) -> NDArray[Any]:
        out = self._sample(obs.numpy(), deterministic)[0]
        if isinstance(self.action_space, gym.spaces.Box):
            out = np.clip(out, self.action_space.low, self.action_space.high)
        return out

    def _collect(self) -> None:
        """Fill the rollout buffer with n_steps steps of every env."""
        cfg, buf = self.config, self.buffer
        buf.reset()
        obs = self._obs
        assert obs is not None
        while not buf.full:
            valid = ~self._prev_done
            x = self._prepare(obs, update=True)
            actions, logp, v = self._sample(x, False)
            buf.add(x, actions, logp, v, valid)
            obs, rew, term, trunc, _ = self._env_step(actions)
            if self.reward_scaler is not None:
                rew = self.reward_scaler(rew, term | trunc)
            buf.add_outcome(rew, term, trunc)
        buf.compute_advantages(self._sample(self._prepare(obs), True)[2], cfg.gamma, cfg.gae_lambda)

    def _sample(
        self, x: NDArray[Any], deterministic: bool
    ) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any]]:
        """Actions, their log-probabilities and V(s) for prepared observations (NumPy).

        MLP networks act in NumPy (:meth:`ActorCritic.sample_numpy`, drawing from the
        agent's generator), others through torch (drawing from its torch generator).
        """
        if self.net.by_hand:
            return self.net.sample_numpy(x, self.rng, deterministic)
        with torch.inference_mode():
            a, logp, v = self.net.sample(torch.as_tensor(x), self.torch_gen, deterministic)
        return a.numpy(), logp.numpy(), v.numpy()

    def _iteration(self) -> dict[str, float]:
        cfg = self.config
        lr = cfg.learning_rate * (self.progress_remaining if cfg.anneal_lr else 1.0)
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        self._collect()
        out = self._update()
        out["learning_rate"] = lr
        return out

    def _update(self) -> dict[str, float]:
        """n_epochs passes of minibatch Adam steps on the rollout; returns mean metrics."""
        cfg, buf = self.config, self.buffer
        obs = torch.as_tensor(buf.flat("obs"))
        if self.net.by_hand:  # [S, 1] for the hand-written passes, once for the rollout
            obs = ChainPasses.with_ones(obs)
        actions = torch.as_tensor(buf.flat("actions"))
        # the per-step scalars side by side, so a minibatch takes them in one gather
        scalars = torch.as_tensor(
            np.stack([buf.flat(k) for k in ("log_probs", "values", "advantages", "returns")], 1)
        )
        vclip = cfg.clip_range_vf or None
        losses: list[torch.Tensor] = []  # per minibatch, read once at the end
        ratios: list[torch.Tensor] = []
        log_ratios: list[torch.Tensor] = []
        # a minibatch that holds every stored step is the same set in every epoch (only
        # its order differs, and the loss is a mean over it): gathered once
        n_valid, whole = int(buf.valid.sum()), None
        for _ in range(cfg.n_epochs):
            for mb in buf.minibatches(cfg.batch_size, self.rng):
                if whole is None or len(mb) != n_valid:
                    i = torch.from_numpy(mb)
                    old_logp, old_v, advantages, returns = scalars[i].unbind(1)
                    adv = normalized(advantages) if cfg.normalize_advantage else advantages
                    mb_obs, mb_actions = obs[i], actions[i]
                    if len(mb) == n_valid:
                        whole = (old_logp, old_v, adv, returns, mb_obs, mb_actions)
                else:
                    old_logp, old_v, adv, returns, mb_obs, mb_actions = whole
                if self.net.by_hand:  # every gradient is overwritten: no zero_grad
                    logp, entropy, v, cache = self.net.forward_cached(mb_obs, mb_actions, True)
                    log_ratio = logp - old_logp
                    ratio = log_ratio.exp()
                    pg_loss, g_ratio = clipped_surrogate_loss_grad(ratio, adv, cfg.clip_range)
                    v_loss, g_v = value_loss_grad(v, old_v, returns, vclip)
                    ent = entropy.mean()
                    self.net.backward_cached(
                        cache, g_ratio.mul_(ratio), -cfg.ent_coef / len(mb), g_v.mul_(cfg.vf_coef)
                    )
                else:
                    self.optimizer.zero_grad(set_to_none=True)
                    logp, entropy, v = self.net.evaluate_actions(mb_obs, mb_actions)
                    log_ratio = logp - old_logp
                    ratio = log_ratio.exp()
                    pg_loss = clipped_surrogate_loss(ratio, adv, cfg.clip_range)
                    v_loss = value_loss(v, old_v, returns, vclip)
                    ent = entropy.mean()
                    loss = pg_loss + cfg.vf_coef * v_loss - cfg.ent_coef * ent
                    loss.backward()  # type: ignore[no-untyped-call]
                if self._flat is not None:  # the same arithmetic on the one flat tensor
                    self._flat.clip_grad_norm_(cfg.max_grad_norm)
                    fused_adam_step(self.optimizer)
                else:
                    clip_grad_norm(self._params, cfg.max_grad_norm)
                    self.optimizer.step()
                self.n_updates += 1
                losses += (pg_loss.detach(), v_loss.detach(), ent.detach())
                ratios.append(ratio.detach())
                log_ratios.append(log_ratio.detach())
            if cfg.target_kl and float(approx_kl(ratios[-1], log_ratios[-1])) > cfg.target_kl:
                break
        means = torch.stack(losses).view(-1, 3).double().mean(0).tolist()
        ratio, log_ratio = torch.cat(ratios), torch.cat(log_ratios)
        clip_fraction = ((ratio - 1).abs() > cfg.clip_range).double().mean()
        names = ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction")
        values = [*means, float(approx_kl(ratio, log_ratio)), float(clip_fraction)]
        return dict(zip(names, values, strict=True))

    def _state_tensors(self, training_state: bool) -> dict[str, Any]:
        state: dict[str, Any] = {"net": self.net.state_dict()}
        if training_state:
            opt = self.optimizer.state_dict()
            state["optimizer"] = self._flat.state_for_checkpoint(opt) if self._flat else opt
            if self.reward_scaler is not None:
                state["reward_scaler"] = self.reward_scaler.rms.state_dict()
        return state

    def _load_state_tensors(self, tensors: dict[str, Any]) -> None:
        from policylab.deep.common.checkpoint import to_numpy_tree

        self.net.load_state_dict(tensors["net"])
        if "optimizer" in tensors:
            state = tensors["optimizer"]
            if self._flat is not None:  # per parameter (older checkpoints) or concatenated
                state = self._flat.state_from_per_parameter(state)
            self.optimizer.load_state_dict(state)
        if "reward_scaler" in tensors and self.reward_scaler is not None:
            self.reward_scaler.rms.load_state_dict(to_numpy_tree(tensors["reward_scaler"]))
