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
from policylab.deep.common.mlp_grad import ChainPasses, FlatParameters, NumpyMLP, fused_adam_step
from policylab.deep.common.networks import clip_grad_norm
from policylab.deep.dqn.losses import q_learning_targets, td_loss
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


NUMPY_ROWS = 64
"""Up to this many rows, NumPy's forward pass of an MLP costs less than torch's."""


def _q_values(np_net: NumpyMLP | None, net: QNetwork, obs: NDArray[Any]) -> NDArray[np.float32]:
    """Q(s, .) for a batch of observations, as a NumPy array.

    NumPy's forward pass (:class:`~policylab.deep.common.mlp_grad.NumpyMLP`) for up to
    :data:`NUMPY_ROWS` observations, where torch's per-operation cost exceeds the
    arithmetic (a 6-256-256-3 network on 35 rows: about 30 us against 60 us), else
    torch's; the two may round the products differently in the last place.
    """
    if np_net is not None and len(obs) <= NUMPY_ROWS:
        return np_net(obs)  # type: ignore[no-any-return]
    with torch.no_grad():
        return net(torch.from_numpy(obs)).numpy()  # type: ignore[no-any-return]


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
        # the hand-written update keeps all parameters (and gradients) in one flat
        # tensor, each layer as one [W^T; b] block (see ChainPasses)
        chain = self.q.chain
        self._flat: FlatParameters | None = None
        self._passes: ChainPasses | None = None
        if chain is not None:
            self._flat = FlatParameters.of_chain(chain)
            self._passes = ChainPasses(self._flat, cfg.activation)
        self._params = [self._flat.flat] if self._flat else list(self.q.parameters())
        self.optimizer = torch.optim.Adam(self._params, lr=cfg.learning_rate, fused=True)
        # acting on a few observations: the forward pass in NumPy (see NumpyMLP)
        self._np_q = NumpyMLP(self.q.chain, cfg.activation) if self.q.chain else None
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
        # Q_target(S', .) of stored transitions, each computed once per target network
        self._target_q: NDArray[np.float32] | None = None
        target_chain = self.q_target.chain
        self._np_q_target = NumpyMLP(target_chain, cfg.activation) if target_chain else None
        # the target network's forward passes run on [W^T; b] blocks too
        self._flat_target = None if target_chain is None else FlatParameters.of_chain(target_chain)
        self._target_q_fresh = np.zeros(cfg.buffer_size, dtype=bool)

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
        x = obs.numpy()
        return self._greedy(x) if deterministic else self._epsilon_greedy(x)

    def _epsilon_greedy(self, x: NDArray[Any]) -> NDArray[Any]:
        """Epsilon-greedy actions for a batch of prepared observations (NumPy)."""
        n = len(x)
        explore = self.rng.random(n) < self.epsilon
        random_actions = self.rng.integers(0, self.n_actions, n)
        if explore.all():  # no greedy action is needed: skip the forward pass
            return random_actions
        return np.where(explore, random_actions, self._greedy(x))

    def _greedy(self, obs: torch.Tensor | NDArray[Any]) -> NDArray[Any]:
        """argmax_a Q(s, a) for a batch."""
        x = obs.numpy() if isinstance(obs, torch.Tensor) else obs
        return _q_values(self._np_q, self.q, x).argmax(1)  # type: ignore[no-any-return]

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
                actions = self._epsilon_greedy(x)
            next_obs, rew, term, trunc, valid = self._env_step(actions)
            done_steps = int(valid.sum())
            steps += max(done_steps, 1)
            self._since_target += done_steps
            out = self.window.push(x, actions, rew, self._prepare(next_obs), term, trunc, valid)
            if out is not None:
                self._target_q_fresh[self.replay.add(*out)] = False
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
            steps = [self._train_step() for _ in range(self.config.gradient_steps)]
            stats = torch.stack(steps).double().mean(0)
        loss, q_mean = stats.tolist()  # read once, at the end
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

    def _train_steps_by_hand(self) -> torch.Tensor:
        """The round's ``gradient_steps`` steps of :meth:`_train_step`, uniform replay, MLP.

        The same updates with less work: the replay buffer and the target network do
        not change during a round, so its minibatches are drawn at once (G batches of
        B uniform draws are G * B uniform draws) and Q_target(S', .) is computed once
        for every stored transition the round draws that has none for the current
        target network yet (:meth:`_next_target_q`); for DQN the targets y too (Double
        DQN's argmax uses the online network of each step). The gradient is
        backpropagated by hand (:mod:`policylab.deep.common.mlp_grad`), the norm clip
        and Adam act on the flat parameters, and the loss and mean Q are computed once
        from the round's stored TD errors and Q values.

        Returns:
            (2,) the round's mean loss and mean Q(S, A), as a tensor.
        """
        cfg, passes, flat = self.config, self._passes, self._flat
        assert passes is not None and flat is not None
        n, bs = cfg.gradient_steps, cfg.batch_size
        b = self.replay.sample(n * bs)
        obs = passes.with_ones(torch.from_numpy(b.obs))  # [S, 1], once for the round
        actions = torch.from_numpy(b.actions).long().unsqueeze(1)
        returns, discounts = torch.from_numpy(b.returns), torch.from_numpy(b.discounts)
        next_target = self._next_target_q(b.indices)
        double = cfg.double_q
        next_obs = torch.from_numpy(b.next_obs) if double else None
        y_all = None if double else q_learning_targets(returns, discounts, next_target, None)
        # dL/dQ(S, .) = -dL/d delta at the action taken, 0 at the others (delta = y - Q):
        # with dL/d delta = c psi(delta) (td_error_grad: psi = clip(delta, -1, 1) and
        # c = 1/B for Huber, psi = delta and c = 2/B squared), it is psi(delta) times a
        # one-hot row holding -c, made for the whole round at once
        c = (1.0 if cfg.loss == "huber" else 2.0) / bs
        signed_onehot = torch.zeros(n * bs, self.n_actions).scatter_(1, actions, -c)
        td_all, q_taken = torch.empty(n, bs, 1), torch.empty(n, bs, 1)
        psi_buf, grad_out = torch.empty(bs, 1), torch.empty(bs, self.n_actions)
        huber = cfg.loss == "huber"
        per_step = zip(
            [None] * n if y_all is None else y_all.view(n, bs, 1).unbind(0),
            obs.view(n, bs, *obs.shape[1:]).unbind(0),
            actions.view(n, bs, 1).unbind(0),
            signed_onehot.view(n, bs, -1).unbind(0),
            td_all.unbind(0),
            q_taken.unbind(0),
            strict=True,
        )
        for k, (y_k, obs_k, a_k, onehot_k, td_k, q_k) in enumerate(per_step):
            if y_k is None:  # Double DQN: the argmax of this step's online network
                assert next_obs is not None
                s = slice(k * bs, (k + 1) * bs)
                with torch.no_grad():
                    y_k = q_learning_targets(
                        returns[s], discounts[s], next_target[s], self.q(next_obs[s])
                    ).unsqueeze(1)
            q_all = passes.forward(obs_k)
            q = torch.gather(q_all, 1, a_k, out=q_k)
            td = torch.sub(y_k, q, out=td_k)
            psi = torch.clamp(td, -1.0, 1.0, out=psi_buf) if huber else td
            passes.backward(torch.mul(onehot_k, psi, out=grad_out))
            flat.clip_grad_norm_(cfg.max_grad_norm)
            fused_adam_step(self.optimizer)
        self.n_updates += n
        # the mean of the G per-step means of B values is the mean of all G * B
        td64 = td_all.double()
        return torch.stack([td_loss(td64, None, cfg.loss), q_taken.double().mean()])

    def _next_target_q(self, indices: NDArray[np.int64]) -> torch.Tensor:
        """Q_target(S', .) of the stored transitions at ``indices``, shape (len, A).

        The target network is fixed between target updates, so Q_target(S', .) of a
        stored transition is computed once per target network and kept (a slot
        overwritten by a new transition, or a target update, discards it): each round
        runs the target network only over the distinct transitions it draws that have
        no value yet. On CartPole-v1 at the zoo's settings (8,192 draws a round) and on
        Acrobot-v1 (a target kept for 62 rounds) that is a fraction of the draws.
        """
        if self._target_q is None:
            self._target_q = np.empty((self.replay.capacity, self.n_actions), np.float32)
        fresh = self._target_q_fresh
        stale = indices[~fresh[indices]]
        if len(stale):
            need = np.unique(stale)
            self._target_q[need] = _q_values(
                self._np_q_target, self.q_target, self.replay.next_obs[need]
            )
            fresh[need] = True
        return torch.from_numpy(self._target_q[indices])

    def _update_target(self) -> None:
        """theta_target <- tau theta + (1 - tau) theta_target (a copy when tau = 1)."""
        self._target_q_fresh[:] = False
        with torch.no_grad():
            if self.config.tau >= 1.0:
                self.q_target.load_state_dict(self.q.state_dict())
            else:
                for p_t, p in zip(self.q_target.parameters(), self.q.parameters(), strict=True):
                    p_t.lerp_(p, self.config.tau)

    def _state_tensors(self, training_state: bool) -> dict[str, Any]:
        state: dict[str, Any] = {"q": self.q.state_dict(), "q_target": self.q_target.state_dict()}
        if training_state:
            opt = self.optimizer.state_dict()
            state["optimizer"] = self._flat.state_for_checkpoint(opt) if self._flat else opt
            state["replay"] = self.replay.state_dict()
            state["counters"] = {"since_target": self._since_target}
        return state

    def _load_state_tensors(self, tensors: dict[str, Any]) -> None:
        self._target_q_fresh[:] = False
        self.q.load_state_dict(tensors["q"])
        self.q_target.load_state_dict(tensors["q_target"])
        if "optimizer" in tensors:
            state = tensors["optimizer"]
            if self._flat is not None:  # per parameter (older checkpoints) or concatenated
                state = self._flat.state_from_per_parameter(state)
            self.optimizer.load_state_dict(state)
        if "replay" in tensors:
            self.replay.load_state_dict(to_numpy_tree(tensors["replay"]))
        if "counters" in tensors:
            self._since_target = int(tensors["counters"]["since_target"])
