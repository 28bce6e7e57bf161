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
from policylab.deep.common.losses import twin_q_loss, twin_q_loss_grad
from policylab.deep.common.mlp_grad import fused_adam_step
from policylab.deep.common.networks import TwinQNetwork, clip_grad_norm
from policylab.exceptions import InvalidArgumentError, NonFiniteError
from policylab.validation import fmt_number

__all__ = [
    "OffPolicyAgent",
    "OffPolicyConfig",
    "Tensors",
    "TwinQCache",
    "check_bounded_box",
    "twin_q_backward",
    "twin_q_forward",
]

Tensors = dict[str, torch.Tensor]

_ACT_NAMES: dict[type[torch.nn.Module], str] = {
    torch.nn.ReLU: "relu",
    torch.nn.Tanh: "tanh",
    torch.nn.ELU: "elu",
}


@dataclasses.dataclass
class TwinQCache:
    """What :func:`twin_q_backward` needs from :func:`twin_q_forward`.

    Attributes:
        x: (B, obs_dim + action_dim + 1) the first layer's input [s, a, 1].
        w_in: (k, obs_dim + action_dim + 1, H_1) the first layer [W_s; W_a; b].
        hidden: Every hidden layer's output act(z_l), each (k, B, H_l).
        params: The weights then biases the forward pass used.
        act: Activation name.
    """

    x: torch.Tensor
    w_in: torch.Tensor
    hidden: list[torch.Tensor]
    params: list[torch.Tensor]
    act: str


def _act_(h: torch.Tensor, act: str) -> torch.Tensor:
    """act(h) in place on ``h`` (a fresh output of the forward pass)."""
    if act == "relu":
        return torch.relu_(h)
    if act == "tanh":
        return torch.tanh_(h)
    return torch.nn.functional.elu_(h)


def _linear_act(h: torch.Tensor, w: torch.Tensor, b: torch.Tensor, act: str) -> torch.Tensor:
    """act(h W + b) of every critic at once.

    Shapes: h (k, B, H_in), w (k, H_in, H_out), b (k, 1, H_out); the result (k, B, H_out).
    With ReLU the bias and the activation are one pass over the product (``_add_relu_``)
    instead of a copy of the bias into the product's output and a ReLU pass after it.
    """
    if act == "relu":
        return torch.ops.aten._add_relu_(torch.bmm(h, w), b)  # type: ignore[no-any-return]
    return _act_(torch.baddbmm(b, h, w), act)


def _act_backward_(grad: torch.Tensor, h: torch.Tensor, act: str) -> torch.Tensor:
    """dL/dz = dL/dh * act'(z) from the output h = act(z), in place on ``grad``.

    ``grad`` is a fresh tensor of the backward pass; the kernels are those of autograd's
    own backward, writing into it instead of a new output tensor.
    """
    aten = torch.ops.aten
    if act == "relu":
        return aten.threshold_backward.grad_input(grad, h, 0, grad_input=grad)  # type: ignore[no-any-return]
    if act == "tanh":
        return aten.tanh_backward.grad_input(grad, h, grad_input=grad)  # type: ignore[no-any-return]
    return aten.elu_backward.grad_input(grad, 1.0, 1.0, 1.0, True, h, grad_input=grad)  # type: ignore[no-any-return]


@torch.no_grad()
def twin_q_forward(
    critic: TwinQNetwork,
    obs: torch.Tensor,
    actions: torch.Tensor,
    params: Sequence[torch.Tensor] | None = None,
) -> tuple[torch.Tensor, TwinQCache]:
    """(2, B) Q_1(s, a), Q_2(s, a) without autograd, and what their backward pass needs.

    The same arithmetic as :meth:`TwinQNetwork.forward` (one product [s, a, 1] [W_s;
    W_a; b] for the first layer, one batched product per hidden layer), with the
    one-output layer as one matrix-vector product per critic; ``params`` as there (e.g.
    first-axis slices ``[:1]`` for Q_1 alone, shape (1, B)). Passing the critic's own
    parameters as a list kept by the caller saves collecting them on every call.
    """
    ps: list[torch.Tensor] = list(critic.parameters() if params is None else params)
    act = _ACT_NAMES[type(critic.act)]
    n = len(ps) // 2
    ws, bs = ps[: n + 1], ps[n + 1 :]
    k = len(ws[0])
    x = torch.cat([obs.reshape(len(obs), -1), actions, obs.new_ones((len(obs), 1))], 1)
    w_in = torch.cat([ws[0], ws[1], bs[0]], 1)
    h = _act_(torch.bmm(x.unsqueeze(0).expand(k, -1, -1), w_in), act)
    hidden = [h]
    for i in range(1, n - 1):
        h = _linear_act(h, ws[i + 1], bs[i], act)
        hidden.append(h)
    q = h.new_empty((k, len(obs)))
    w_out, b_out = ws[n].reshape(k, -1), bs[n - 1].reshape(k)
    for i in range(k):  # Q_i = h_n w + b, a matrix-vector product with the bias added in
        torch.addmv(b_out[i], h[i], w_out[i], out=q[i])
    return q, TwinQCache(x, w_in, hidden, ps, act)


def _grad_buffer(p: torch.Tensor) -> torch.Tensor:
    """``p.grad``, created (uninitialised) if ``p`` has none; it is then overwritten."""
    if p.grad is None:
        p.grad = torch.empty_like(p)
    return p.grad


@torch.no_grad()
def twin_q_backward(
    cache: TwinQCache, dq: torch.Tensor, param_grads: bool = True, action_grad: bool = False
) -> torch.Tensor | None:
    """Backpropagate dL/dQ through the twin critics by hand (no autograd graph).

    With z_l = h_{l-1} W_l + b_l, h_l = act(z_l) and Q = h_n w + b per critic:

        dw = sum_batch dQ h_n,  db = sum_batch dQ,  dh_n = dQ w^T,
        dz_l = dh_l * act'(z_l),  dW_l = h_{l-1}^T dz_l,  db_l = sum_batch dz_l,
        dh_{l-1} = dz_l W_l^T,

    and for the first layer dW_in = [s, a, 1]^T dz_1 (the rows of W_s, W_a and b), and
    dL/da = sum_i dz_1 W_a^T. The same products autograd runs, without its graph; the
    activations' derivatives are applied in place on the products' outputs.

    Args:
        cache: From :func:`twin_q_forward`.
        dq: (k, B) dL/dQ_i(s_b, a_b).
        param_grads: Write dL/dtheta into the ``.grad`` of the parameters the forward
            pass used (overwriting it); False for an actor's loss, whose critics are
            held constant.
        action_grad: Also return dL/da, (B, action_dim).

    Returns:
        dL/da, or None without ``action_grad``.
    """
    ps, act, hidden = cache.params, cache.act, cache.hidden
    n = len(ps) // 2
    ws, bs = ps[: n + 1], ps[n + 1 :]
    k = len(ws[0])
    h = hidden[-1]
    if param_grads:
        torch.sum(dq, 1, keepdim=True, out=_grad_buffer(bs[n - 1]).view(k, 1))
        out = _grad_buffer(ws[n]).view(k, 1, -1)
        torch.bmm(dq.unsqueeze(1), h, out=out)
    # dh_n = dQ w^T as a batched outer product, then act' in place
    g = _act_backward_(torch.bmm(dq.unsqueeze(-1), ws[n].reshape(k, 1, -1)), h, act)
    for i in range(len(hidden) - 2, -1, -1):  # the layer after hidden[i]: ws[i + 2], bs[i + 1]
        h_in = hidden[i]
        if param_grads:
            torch.sum(g, 1, keepdim=True, out=_grad_buffer(bs[i + 1]))
            torch.bmm(h_in.transpose(1, 2), g, out=_grad_buffer(ws[i + 2]))
        g = _act_backward_(torch.bmm(g, ws[i + 2].transpose(1, 2)), h_in, act)
    if param_grads:
        d_in = torch.bmm(cache.x.t().unsqueeze(0).expand(k, -1, -1), g)
        n_obs, n_act = ws[0].shape[1], ws[1].shape[1]
        _grad_buffer(ws[0]).copy_(d_in[:, :n_obs])
        _grad_buffer(ws[1]).copy_(d_in[:, n_obs : n_obs + n_act])
        _grad_buffer(bs[0]).copy_(d_in[:, n_obs + n_act :])
    if not action_grad:
        return None
    w_act = ws[1]  # (k, action_dim, H_1): dL/da = sum_i dz_1,i W_a,i^T
    grad_a = torch.mm(g[0], w_act[0].t())
    for i in range(1, k):
        grad_a.addmm_(g[i], w_act[i].t())
    return grad_a


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
        # the parameter lists the updates pass around, collected once
        self._critic_params = list(self.critic.parameters())
        self._target_params = list(self.critic_target.parameters())
        self.critic_optimizer = torch.optim.Adam(
            self._critic_params, lr=cfg.learning_rate, fused=True
        )

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
        (:func:`twin_q_forward`, :func:`twin_q_backward`), from the loss's own gradient
        (:func:`~policylab.deep.common.losses.twin_q_loss_grad`): no autograd graph.

        Returns:
            The loss and (2, B) Q_1(S, A), Q_2(S, A), both detached.
        """
        q, cache = twin_q_forward(self.critic, obs, actions, self._critic_params)
        loss = twin_q_loss(q, targets)
        twin_q_backward(cache, twin_q_loss_grad(q, targets))
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
