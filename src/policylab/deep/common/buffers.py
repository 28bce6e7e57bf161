"""Experience storage: replay buffers (uniform, prioritized), n-step windows, rollouts.

Replay buffers store transitions already reduced to what a Q-learning target needs:
``(obs, action, return, next_obs, discount)`` with ``return`` the (n-step) return
G_{t:t+m} and ``discount`` the bootstrap weight gamma^m (1 - terminated), so the target
is ``return + discount * max_a Q(next_obs, a)`` whatever n is.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from policylab.deep.common.returns import gae_advantages, n_step_targets
from policylab.exceptions import CheckpointError, InvalidArgumentError

__all__ = [
    "NStepWindow",
    "PrioritizedReplayBuffer",
    "ReplayBatch",
    "ReplayBuffer",
    "RolloutBuffer",
]


@dataclass
class ReplayBatch:
    """A sampled minibatch of transitions (NumPy arrays, first axis the batch)."""

    indices: NDArray[np.int64]
    obs: NDArray[Any]
    actions: NDArray[Any]
    returns: NDArray[np.float32]
    next_obs: NDArray[Any]
    discounts: NDArray[np.float32]
    weights: NDArray[np.float32]
    """Importance-sampling weights (all ones for the uniform buffer)."""


class ReplayBuffer:
    """A fixed-size circular buffer of transitions, sampled uniformly.

    Args:
        capacity: Number of transitions kept; the oldest is overwritten first.
        obs_shape: Shape of one observation.
        obs_dtype: Stored dtype (``uint8`` for pixels keeps Atari frames small).
        action_shape: Shape of one action (``()`` for discrete actions).
        action_dtype: Stored action dtype.
        seed: Seed or generator of the sampling.
    """

    def __init__(
        self,
        capacity: int,
        obs_shape: tuple[int, ...],
        obs_dtype: Any = np.float32,
        action_shape: tuple[int, ...] = (),
        action_dtype: Any = np.int64,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        if int(capacity) != capacity or capacity < 1:
            raise InvalidArgumentError(f"capacity must be an integer >= 1; got {capacity!r}")
        self.capacity = int(capacity)
        self.obs = np.zeros((self.capacity, *obs_shape), dtype=obs_dtype)
        self.next_obs = np.zeros((self.capacity, *obs_shape), dtype=obs_dtype)
        self.actions = np.zeros((self.capacity, *action_shape), dtype=action_dtype)
        self.returns = np.zeros(self.capacity, dtype=np.float32)
        self.discounts = np.zeros(self.capacity, dtype=np.float32)
        self.pos = 0
        self.size = 0
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return self.size

    def add(
        self,
        obs: NDArray[Any],
        actions: NDArray[Any],
        returns: NDArray[Any],
        next_obs: NDArray[Any],
        discounts: NDArray[Any],
    ) -> NDArray[np.int64]:
        """Store a batch of transitions (first axis); return the slots they went to."""
        k = len(returns)
        if self.pos + k <= self.capacity:  # no wrap-around: slices, cheaper than indices
            idx = np.arange(self.pos, self.pos + k)
            s = slice(self.pos, self.pos + k)
            self.obs[s], self.next_obs[s], self.actions[s] = obs, next_obs, actions
            self.returns[s], self.discounts[s] = returns, discounts
            self.pos = (self.pos + k) % self.capacity
            self.size = min(self.size + k, self.capacity)
            return idx
        idx = (self.pos + np.arange(k)) % self.capacity
        self.obs[idx] = obs
        self.next_obs[idx] = next_obs
        self.actions[idx] = actions
        self.returns[idx] = returns
        self.discounts[idx] = discounts
        self.pos = int((self.pos + k) % self.capacity)
        self.size = min(self.size + k, self.capacity)
        return idx

    def _batch(self, idx: NDArray[np.int64], weights: NDArray[np.float32]) -> ReplayBatch:
        return ReplayBatch(
            idx, self.obs[idx], self.actions[idx], self.returns[idx], self.next_obs[idx],
            self.discounts[idx], weights,
        )  # fmt: skip

    def sample(self, batch_size: int) -> ReplayBatch:
        """A minibatch drawn uniformly with replacement from the stored transitions."""
        if self.size == 0:
            raise InvalidArgumentError("cannot sample from an empty replay buffer")
        idx = self.rng.integers(0, self.size, size=batch_size)
        return self._batch(idx, np.ones(batch_size, dtype=np.float32))

    def state_dict(self) -> dict[str, Any]:
        """The stored transitions and position, as plain arrays (for checkpoints)."""
        n = self.size
        return {
            "obs": self.obs[:n], "next_obs": self.next_obs[:n], "actions": self.actions[:n],
            "returns": self.returns[:n], "discounts": self.discounts[:n],
            "pos": np.array(self.pos), "size": np.array(self.size),
        }  # fmt: skip

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`state_dict` gave."""
        try:
            n = int(state["size"])
            if n > self.capacity:
                raise CheckpointError(
                    f"replay buffer holds {n} transitions; capacity is {self.capacity}"
                )
            for name in ("obs", "next_obs", "actions", "returns", "discounts"):
                getattr(self, name)[:n] = state[name]
            self.size, self.pos = n, int(state["pos"])
        except (KeyError, ValueError) as e:
            raise CheckpointError(f"replay buffer state does not fit this buffer: {e}") from None


class PrioritizedReplayBuffer(ReplayBuffer):
    """Proportional prioritized replay (Schaul et al. 2016) on a sum tree.

    P(i) = p_i^alpha / sum_k p_k^alpha, with p_i = |delta_i| + eps the last TD error of
    transition i (new transitions get the largest priority seen so far), and
    importance-sampling weights w_i = (N P(i))^(-beta) / max_j w_j.

    Args:
        capacity: Number of transitions kept.
        obs_shape: Shape of one observation.
        obs_dtype: Stored observation dtype.
        action_shape: Shape of one action.
        action_dtype: Stored action dtype.
        alpha: How much prioritization is used (0 is uniform).
        eps: Added to |delta| so no transition has zero probability.
        seed: Seed or generator of the sampling.
    """

    def __init__(
        self,
        capacity: int,
        obs_shape: tuple[int, ...],
        obs_dtype: Any = np.float32,
        action_shape: tuple[int, ...] = (),
        action_dtype: Any = np.int64,
        alpha: float = 0.6,
        eps: float = 1e-6,
        seed: int | np.random.Generator | None = None,
    ) -> None:
        super().__init__(capacity, obs_shape, obs_dtype, action_shape, action_dtype, seed)
        if alpha < 0:
            raise InvalidArgumentError(f"alpha must be >= 0; got {alpha!r}")
        self.alpha, self.eps = float(alpha), float(eps)
        self.leaves = 1 << max(0, (self.capacity - 1).bit_length())
        self.tree = np.zeros(
            2 * self.leaves
        )  # node i has children 2i, 2i+1; leaves at [leaves, 2 leaves)
        self.max_priority = 1.0

    def _set(self, idx: NDArray[np.int64], priorities: NDArray[np.float64]) -> None:
        nodes = np.asarray(idx, dtype=np.int64) + self.leaves
        self.tree[nodes] = priorities
        nodes = np.unique(nodes // 2)
        while nodes[0] >= 1:
            self.tree[nodes] = self.tree[2 * nodes] + self.tree[2 * nodes + 1]
            if nodes[0] == 1:
                break
            nodes = np.unique(nodes // 2)

    def add(
        self,
        obs: NDArray[Any],
        actions: NDArray[Any],
        returns: NDArray[Any],
        next_obs: NDArray[Any],
        discounts: NDArray[Any],
    ) -> NDArray[np.int64]:
        """Store transitions with the largest priority seen so far."""
        idx = super().add(obs, actions, returns, next_obs, discounts)
        self._set(idx, np.full(len(idx), self.max_priority**self.alpha))
        return idx

    def sample(self, batch_size: int, beta: float = 0.4) -> ReplayBatch:
        """A minibatch drawn with probability P(i), with importance weights for ``beta``."""
        if self.size == 0:
            raise InvalidArgumentError("cannot sample from an empty replay buffer")
        total = self.tree[1]
        # stratified: one uniform draw in each of batch_size equal slices of the total mass
        u = (np.arange(batch_size) + self.rng.random(batch_size)) * (total / batch_size)
        node = np.ones(batch_size, dtype=np.int64)
        while node[0] < self.leaves:
            left = 2 * node
            go_right = u >= self.tree[left]
            u = np.where(go_right, u - self.tree[left], u)
            node = left + go_right
        idx = np.minimum(node - self.leaves, self.size - 1)
        probs = self.tree[idx + self.leaves] / total
        leaves = self.tree[self.leaves : self.leaves + self.size]
        min_prob = leaves[leaves > 0].min() / total
        weights = (probs / min_prob) ** (-beta)
        return self._batch(idx, weights.astype(np.float32))

    def update_priorities(self, indices: NDArray[np.int64], td_errors: NDArray[Any]) -> None:
        """Set p_i = |delta_i| + eps for the sampled transitions."""
        p = np.abs(np.asarray(td_errors, dtype=np.float64)) + self.eps
        self.max_priority = max(self.max_priority, float(p.max()))
        self._set(indices, p**self.alpha)

    def state_dict(self) -> dict[str, Any]:
        """Transitions plus the priorities."""
        out = super().state_dict()
        out["priorities"] = self.tree[self.leaves : self.leaves + self.size].copy()
        out["max_priority"] = np.array(self.max_priority)
        return out

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`state_dict` gave."""
        super().load_state_dict(state)
        try:
            self.tree[:] = 0.0
            if self.size:
                self._set(np.arange(self.size), np.asarray(state["priorities"], dtype=np.float64))
            self.max_priority = float(state["max_priority"])
        except (KeyError, ValueError) as e:
            raise CheckpointError(
                f"prioritized replay state does not fit this buffer: {e}"
            ) from None


class NStepWindow:
    """Turns the one-step transitions of N parallel envs into n-step transitions.

    Each env keeps its last n steps; a step leaves the window as
    ``(S_t, A_t, G_{t:t+n}, S_{t+n}, gamma^n)`` once n later steps are known, and every
    pending step leaves at once (with a shorter return, see :func:`n_step_targets`)
    when the episode ends, bootstrapped after a truncation and not after a termination.

    Args:
        n_envs: Number of parallel environments.
        n: Number of steps of the return (1 is ordinary one-step Q-learning).
        gamma: Discount rate.
    """

    def __init__(self, n_envs: int, n: int, gamma: float) -> None:
        self.n, self.gamma = int(n), float(gamma)
        self.windows: list[deque[tuple[Any, Any, float]]] = [deque() for _ in range(n_envs)]

    def push(
        self,
        obs: NDArray[Any],
        actions: NDArray[Any],
        rewards: NDArray[Any],
        next_obs: NDArray[Any],
        terminated: NDArray[np.bool_],
        truncated: NDArray[np.bool_],
        valid: NDArray[np.bool_],
    ) -> tuple[NDArray[Any], NDArray[Any], NDArray[Any], NDArray[Any], NDArray[Any]] | None:
        """Add one vector step; return the transitions that are complete (or None).

        ``valid`` is False for the envs whose step only reset them (an autoreset step
        carries no transition).
        """
        if self.n == 1:  # the common case, vectorised
            disc = np.where(terminated, 0.0, self.gamma)
            if valid.all():  # no env only reset: every step is a transition
                return obs, actions, rewards, next_obs, disc
            if not valid.any():
                return None
            return obs[valid], actions[valid], rewards[valid], next_obs[valid], disc[valid]
        out: list[tuple[Any, Any, float, Any, float]] = []
        for i in np.flatnonzero(valid):
            w = self.windows[i]
            w.append((obs[i], actions[i], float(rewards[i])))
            done = bool(terminated[i] or truncated[i])
            if not done and len(w) < self.n:
                continue
            r = np.array([x[2] for x in w])
            term = np.zeros(len(w), dtype=bool)
            term[-1] = bool(terminated[i])
            trunc = np.zeros(len(w), dtype=bool)
            trunc[-1] = bool(truncated[i])
            g, disc, _ = n_step_targets(r, term, trunc, self.gamma, self.n)
            emit = len(w) if done else 1
            for k in range(emit):
                o, a, _ = w.popleft()
                out.append((o, a, g[k], next_obs[i], disc[k]))
        if not out:
            return None
        cols = list(zip(*out, strict=True))
        return (
            np.stack(cols[0]), np.stack(cols[1]), np.array(cols[2]), np.stack(cols[3]),
            np.array(cols[4]),
        )  # fmt: skip


class RolloutBuffer:
    """On-policy storage of T steps of N envs, with GAE advantages and returns.

    Steps on which an env only reset itself (the step after its episode ended, under
    Gymnasium's next-step autoreset) are stored with ``valid = False`` and never used
    in a loss; the value computed for them is V of the episode's last state, which is
    exactly the bootstrap a truncated step needs.

    Args:
        n_steps: T, steps per env per rollout.
        n_envs: N.
        obs_shape: Shape of one observation.
        action_shape: Shape of one action.
        obs_dtype: Stored observation dtype.
        action_dtype: Stored action dtype.
    """

    def __init__(
        self,
        n_steps: int,
        n_envs: int,
        obs_shape: tuple[int, ...],
        action_shape: tuple[int, ...],
        obs_dtype: Any = np.float32,
        action_dtype: Any = np.int64,
    ) -> None:
        T, N = n_steps, n_envs
        self.n_steps, self.n_envs = T, N
        self.obs = np.zeros((T, N, *obs_shape), dtype=obs_dtype)
        self.actions = np.zeros((T, N, *action_shape), dtype=action_dtype)
        self.log_probs = np.zeros((T, N), dtype=np.float32)
        self.rewards = np.zeros((T, N), dtype=np.float32)
        self.values = np.zeros((T, N), dtype=np.float32)
        self.terminated = np.zeros((T, N), dtype=bool)
        self.truncated = np.zeros((T, N), dtype=bool)
        self.valid = np.zeros((T, N), dtype=bool)
        self.advantages = np.zeros((T, N), dtype=np.float32)
        self.returns = np.zeros((T, N), dtype=np.float32)
        self.t = 0

    def add(
        self,
        obs: NDArray[Any],
        actions: NDArray[Any],
        log_probs: NDArray[Any],
        values: NDArray[Any],
        valid: NDArray[np.bool_],
    ) -> None:
        """Store what the agent saw and chose at step t (before stepping the envs)."""
        t = self.t
        self.obs[t], self.actions[t], self.log_probs[t] = obs, actions, log_probs
        self.values[t], self.valid[t] = values, valid

    def add_outcome(
        self, rewards: NDArray[Any], terminated: NDArray[np.bool_], truncated: NDArray[np.bool_]
    ) -> None:
        """Store what the envs answered to step t, and move to t + 1."""
        t = self.t
        self.rewards[t], self.terminated[t], self.truncated[t] = rewards, terminated, truncated
        self.t += 1

    @property
    def full(self) -> bool:
        """Whether T steps are stored."""
        return self.t >= self.n_steps

    def compute_advantages(
        self, last_values: NDArray[Any], gamma: float, gae_lambda: float
    ) -> None:
        """GAE advantages and value targets, bootstrapping from V(S_T) = ``last_values``."""
        next_values = np.concatenate(
            [self.values[1:], np.asarray(last_values, np.float32)[None]], axis=0
        )
        adv = gae_advantages(
            self.rewards,
            self.values,
            next_values,
            self.terminated,
            self.truncated,
            gamma,
            gae_lambda,
        )
        self.advantages[:] = adv
        self.returns[:] = adv + self.values

    def minibatches(self, batch_size: int, rng: np.random.Generator) -> Iterator[NDArray[np.int64]]:
        """Shuffled flat indices (into the T*N steps) of the valid steps, in minibatches."""
        idx = np.flatnonzero(self.valid.reshape(-1))
        idx = idx[rng.permutation(len(idx))]
        n_batches = max(1, round(len(idx) / batch_size))
        yield from np.array_split(idx, n_batches)

    def flat(self, name: str) -> NDArray[Any]:
        """A stored array with its (T, N) axes merged into one."""
        a: NDArray[Any] = getattr(self, name)
        return a.reshape(self.n_steps * self.n_envs, *a.shape[2:])

    def reset(self) -> None:
        """Start the next rollout."""
        self.t = 0
