"""Deep Q-networks with Double DQN, dueling heads, n-step returns and prioritized replay."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from policylab.deep.common.agent import Agent, BaseConfig
from policylab.deep.common.buffers import NStepWindow, PrioritizedReplayBuffer, ReplayBuffer
from policylab.deep.common.checkpoint import to_numpy_tree
from policylab.deep.common.config import check, check_replay_settings, documented, option
from policylab.deep.common.mlp_grad import FlatParameters, mlp_backward, mlp_forward
from policylab.deep.common.networks import clip_grad_norm
from policylab.deep.dqn.losses import q_learning_targets, td_loss, td_loss_grad
from policylab.deep.dqn.networks import QNetwork

__all__ = ["DQN", "DQNConfig"]


@documented
@dataclasses.dataclass
class DQNConfig(BaseConfig):
    """Hyperparameters of :class:`DQN` (the same names in config files and the CLI)."""

    learning_rate: float = option(1e-4, "Adam step size.")
    hidden: tuple[int, ...] = option((256, 256), "Hidden layer sizes of the Q-network MLP.")
    activation: str = option("relu", "Activation of the MLP hidden layers: tanh, relu or elu.")
    buffer_size: int = option(100_000, "Replay buffer capacity in transitions.")
    learning_starts: int = option(
        1000, "Env steps of random-policy experience before the first update."
    )
    batch_size: int = option(32, "Minibatch size of each gradient step.")
    train_freq: int = option(4, "Env steps (summed over envs) between rounds of gradient steps.")
    gradient_steps: int = option(1, "Gradient steps in each round.")
    target_update_interval: int = option(1000, "Env steps between target-network updates.")
    tau: float = option(
        1.0, "Target update weight: 1 copies the online network, < 1 is Polyak averaging."
    )
    exploration_fraction: float = option(
        0.1, "Fraction of the run over which epsilon decays linearly."
    )
    exploration_initial_eps: float = option(1.0, "epsilon at the start.")
    exploration_final_eps: float = option(0.05, "epsilon after the decay.")
    double_q: bool = option(
        True, "Double DQN targets (the online network picks the bootstrap action)."
    )
    dueling: bool = option(False, "Dueling head: Q = V + A - mean(A).")
    n_step: int = option(1, "Steps of the bootstrapped return (n-step Q-learning).")
    prioritized: bool = option(False, "Proportional prioritized replay instead of uniform.")
    per_alpha: float = option(0.6, "Prioritization exponent alpha.")
    per_beta: float = option(0.4, "Initial importance-sampling exponent beta (annealed to 1).")
    loss: str = option("huber", "TD loss: huber or mse.")

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        super().validate()
        check_replay_settings(self)
        check(self.target_update_interval >= 1, "target_update_interval must be >= 1")
        check(0.0 <= self.exploration_fraction <= 1.0, "exploration_fraction must be in [0, 1]")
        for name in ("exploration_initial_eps", "exploration_final_eps"):
            v = getattr(self, name)
            check(0.0 <= v <= 1.0, f"{name} must be in [0, 1]; got {v}")
        check(self.n_step >= 1, f"n_step must be >= 1; got {self.n_step}")
        check(
            self.per_alpha >= 0 and 0.0 <= self.per_beta <= 1.0,
            "per_alpha must be >= 0 and per_beta in [0, 1]",
        )
        check(self.loss in ("huber", "mse"), f"loss must be 'huber' or 'mse'; got {self.loss!r}")


class DQN(Agent):
    """DQN: epsilon-greedy experience in a replay buffer and TD updates toward a target network.

    Every ``train_freq`` env steps it takes ``gradient_steps`` Adam steps on the
    (importance-weighted) Huber loss of y - Q(S_t, A_t), where y is the n-step
    (Double) Q-learning target of :func:`~policylab.deep.dqn.losses.q_learning_targets`;
    the target network follows the online one every ``target_update_interval`` steps.

    Example:
        >>> import policylab as pl
        >>> agent = pl.deep.DQN("CartPole-v1", learning_starts=1000)  # doctest: +SKIP
        >>> agent.learn(50_000)                                       # doctest: +SKIP
    """

    algo = "dqn"
    config_class = DQNConfig
    config: DQNConfig

    def _build(self) -> None:
        cfg = self.config
        self.q = QNetwork(
            self.observation_space,
            self.action_space,
            cfg.hidden,
            cfg.activation,
            cfg.dueling,
            self.torch_gen,
        )
        self.q_target = copy.deepcopy(self.q).requires_grad_(False)
        # the hand-written update keeps all parameters (and gradients) in one flat tensor
        self._flat = FlatParameters(list(self.q.parameters())) if self.q.chain else None
        self._params = [self._flat.flat] if self._flat else list(self.q.parameters())
        self.optimizer = torch.optim.Adam(self._params, lr=cfg.learning_rate, fused=True)
        shape = tuple(self.observation_space.shape or ())
        obs_dtype = np.uint8 if self.observation_space.dtype == np.uint8 else np.float32
        if cfg.prioritized:
            self.replay: ReplayBuffer = PrioritizedReplayBuffer(
                cfg.buffer_size, shape, obs_dtype, alpha=cfg.per_alpha, seed=self.rng
            )
        else:
            self.replay = ReplayBuffer(cfg.buffer_size, shape, obs_dtype, seed=self.rng)
        self.window = NStepWindow(cfg.n_envs, cfg.n_step, cfg.gamma)
        self._since_target = 0

    @property
    def epsilon(self) -> float:
        """Exploration rate now: linear from initial to final over the exploration fraction."""
        cfg = self.config
        span = cfg.exploration_fraction * max(self.target_steps, 1)
        frac = 1.0 if span == 0 else min(1.0, self.num_timesteps / span)
        return cfg.exploration_initial_eps + frac * (
            cfg.exploration_final_eps - cfg.exploration_initial_eps
        )

    @property
    def n_actions(self) -> int:
        """Number of discrete actions."""
        return int(getattr(self.action_space, "n", 0))

    def _act(self, obs: torch.Tensor, deterministic: bool) -> NDArray[Any]:
        greedy: NDArray[Any] = self.q(obs).argmax(dim=1).numpy()
        if deterministic:
            return greedy
        explore = self.rng.random(len(greedy)) < self.epsilon
        return np.where(explore, self.rng.integers(0, self.n_actions, len(greedy)), greedy)

    def _iteration(self) -> dict[str, float]:
        cfg = self.config
        n = self.envs.num_envs
        obs = self._obs
        assert obs is not None
        # collect train_freq env steps with the epsilon-greedy policy
        steps = 0
        while steps < cfg.train_freq:
            x = self._prepare(obs, update=True)
            if self.num_timesteps < cfg.learning_starts:
                actions = self.rng.integers(0, self.n_actions, n)
            else:
                with torch.inference_mode():
                    actions = self._act(torch.as_tensor(x), deterministic=False)
            next_obs, rew, term, trunc, valid = self._env_step(actions)
            done_steps = int(valid.sum())
            steps += max(done_steps, 1)
            self._since_target += done_steps
            out = self.window.push(x, actions, rew, self._prepare(next_obs), term, trunc, valid)
            if out is not None:
                self.replay.add(*out)
            obs = next_obs
        metrics: dict[str, float] = {"epsilon": self.epsilon}
        if self.num_timesteps >= cfg.learning_starts and len(self.replay) >= cfg.batch_size:
            metrics.update(self._update())
        if self._since_target >= cfg.target_update_interval:
            self._since_target %= cfg.target_update_interval
            self._update_target()
        return metrics

    def _update(self) -> dict[str, float]:
        """``gradient_steps`` gradient steps; returns their mean loss and Q (none if 0 steps)."""
        if self.config.gradient_steps == 0:
            return {}
        if self.q.chain is not None and not isinstance(self.replay, PrioritizedReplayBuffer):
            stats = self._train_steps_by_hand()
        else:
            stats = [self._train_step() for _ in range(self.config.gradient_steps)]
        loss, q_mean = torch.stack(stats).double().mean(0).tolist()  # read once, at the end
        return {"loss": loss, "q_mean": q_mean}

    def _train_step(self) -> torch.Tensor:
        """One gradient step; returns its (loss, mean Q) as a detached tensor."""
        cfg = self.config
        if isinstance(self.replay, PrioritizedReplayBuffer):
            beta = cfg.per_beta + (1.0 - cfg.per_beta) * (1.0 - self.progress_remaining)
            b = self.replay.sample(cfg.batch_size, beta=beta)
        else:
            b = self.replay.sample(cfg.batch_size)
        obs, next_obs = torch.as_tensor(b.obs), torch.as_tensor(b.next_obs)
        with torch.no_grad():
            next_target = self.q_target(next_obs)
            # Double DQN's online pass over S' needs no graph: outside the backward pass
            # it costs one forward, where a joint pass over [S; S'] doubled the backward.
            next_online = self.q(next_obs) if cfg.double_q else None
        q_obs = self.q(obs)
        y = q_learning_targets(
            torch.as_tensor(b.returns), torch.as_tensor(b.discounts), next_target, next_online
        )
        q = q_obs.gather(1, torch.as_tensor(b.actions).long().unsqueeze(1)).squeeze(1)
        td = y - q
        loss = td_loss(td, torch.as_tensor(b.weights), cfg.loss)
        if self._flat is not None:  # autograd adds into the flat gradient's views
            self._flat.flat.grad.zero_()  # type: ignore[union-attr]
        else:
            self.optimizer.zero_grad(set_to_none=True)
        loss.backward()  # type: ignore[no-untyped-call]
        clip_grad_norm(self._params, cfg.max_grad_norm)
        self.optimizer.step()
        self.n_updates += 1
        if isinstance(self.replay, PrioritizedReplayBuffer):
            self.replay.update_priorities(b.indices, td.detach().numpy())
        return torch.stack([loss.detach(), q.detach().mean()])

    def _train_steps_by_hand(self) -> list[torch.Tensor]:
        """The round's ``gradient_steps`` steps of :meth:`_train_step`, uniform replay, MLP.

        The same updates with less work: the replay buffer and the target network do
        not change during a round, so its minibatches are drawn at once (G batches of
        B uniform draws are G * B uniform draws) and Q_target(S', .) is one forward pass
        over all of them (for DQN the targets y too; Double DQN's argmax uses the online
        network of each step). The gradient is backpropagated by hand
        (:mod:`policylab.deep.common.mlp_grad`).
        """
        cfg, chain = self.config, self.q.chain
        assert chain is not None
        n, bs = cfg.gradient_steps, cfg.batch_size
        b = self.replay.sample(n * bs)
        obs, next_obs = torch.as_tensor(b.obs), torch.as_tensor(b.next_obs)
        actions = torch.as_tensor(b.actions).long().unsqueeze(1)
        returns, discounts = torch.as_tensor(b.returns), torch.as_tensor(b.discounts)
        weights = torch.as_tensor(b.weights)
        with torch.no_grad():
            next_target = self.q_target(next_obs)
            y_all = (
                None if cfg.double_q else q_learning_targets(returns, discounts, next_target, None)
            )
        stats = []
        for k in range(n):
            s = slice(k * bs, (k + 1) * bs)
            if y_all is None:
                with torch.no_grad():
                    y = q_learning_targets(
                        returns[s], discounts[s], next_target[s], self.q(next_obs[s])
                    )
            else:
                y = y_all[s]
            q_all, inputs = mlp_forward(chain, self.q.act, obs[s])
            a = actions[s]
            q = q_all.gather(1, a).squeeze(1)
            loss, g_td = td_loss_grad(y - q, weights[s], cfg.loss)
            # dL/dQ(S, .) is -dL/d delta at the action taken, 0 at the others (delta = y - Q)
            g_out = torch.zeros_like(q_all).scatter_(1, a, g_td.neg_().unsqueeze(1))
            mlp_backward(chain, self.q.act, inputs, g_out)
            clip_grad_norm(self._params, cfg.max_grad_norm)
            self.optimizer.step()
            self.n_updates += 1
            stats.append(torch.stack([loss, q.mean()]))
        return stats

    def _update_target(self) -> None:
        """theta_target <- tau theta + (1 - tau) theta_target (a copy when tau = 1)."""
        with torch.no_grad():
            if self.config.tau >= 1.0:
                self.q_target.load_state_dict(self.q.state_dict())
            else:
                for p_t, p in zip(self.q_target.parameters(), self.q.parameters(), strict=True):
                    p_t.lerp_(p, self.config.tau)

    def _state_tensors(self, training_state: bool) -> dict[str, Any]:
        state: dict[str, Any] = {"q": self.q.state_dict(), "q_target": self.q_target.state_dict()}
        if training_state:
            state["optimizer"] = self.optimizer.state_dict()
            state["replay"] = self.replay.state_dict()
            state["counters"] = {"since_target": self._since_target}
        return state

    def _load_state_tensors(self, tensors: dict[str, Any]) -> None:
        self.q.load_state_dict(tensors["q"])
        self.q_target.load_state_dict(tensors["q_target"])
        if "optimizer" in tensors:
            state = tensors["optimizer"]
            if self._flat is not None:  # a checkpoint from before the flat parameters
                state = self._flat.state_from_per_parameter(state)
            self.optimizer.load_state_dict(state)
        if "replay" in tensors:
            self.replay.load_state_dict(to_numpy_tree(tensors["replay"]))
        if "counters" in tensors:
            self._since_target = int(tensors["counters"]["since_target"])
