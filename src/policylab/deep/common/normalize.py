"""Running observation and reward normalisation (kept with the agent and its checkpoints)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ObservationNormalizer", "RewardScaler", "RunningMeanStd"]


class RunningMeanStd:
    """Mean and variance of a stream of batches (Chan et al.'s parallel update).

    Args:
        shape: Shape of one sample.
    """

    def __init__(self, shape: tuple[int, ...] = ()) -> None:
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = 1e-4

    def update(self, batch: NDArray[Any]) -> None:
        """Fold a batch (first axis the samples) into the running moments."""
        b = np.asarray(batch, dtype=np.float64)
        n = b.shape[0]
        if n == 0:
            return
        b_mean, b_var = b.mean(axis=0), b.var(axis=0)
        delta = b_mean - self.mean
        total = self.count + n
        self.mean = self.mean + delta * n / total
        m2 = self.var * self.count + b_var * n + delta**2 * self.count * n / total
        self.var = m2 / total
        self.count = total

    def state_dict(self) -> dict[str, Any]:
        """The moments as arrays."""
        return {"mean": self.mean.copy(), "var": self.var.copy(), "count": np.array(self.count)}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`state_dict` gave."""
        self.mean = np.asarray(state["mean"], dtype=np.float64)
        self.var = np.asarray(state["var"], dtype=np.float64)
        self.count = float(state["count"])


class ObservationNormalizer:
    """o -> clip((o - mean) / sqrt(var + eps), -clip, clip) with running moments.

    Args:
        shape: Shape of one observation.
        clip: Bound of the normalised values.
        eps: Added to the variance.
    """

    def __init__(self, shape: tuple[int, ...], clip: float = 10.0, eps: float = 1e-8) -> None:
        self.rms = RunningMeanStd(shape)
        self.clip, self.eps = clip, eps

    def __call__(self, obs: NDArray[Any], update: bool = False) -> NDArray[np.float32]:
        """Normalise a batch of observations, first folding it into the moments if ``update``."""
        if update:
            self.rms.update(obs)
        z = (obs - self.rms.mean) / np.sqrt(self.rms.var + self.eps)
        return np.clip(z, -self.clip, self.clip).astype(np.float32)


class RewardScaler:
    """Divides rewards by the running standard deviation of the discounted return.

    The return R_t = gamma R_{t-1} + r_t of each env is tracked (reset at episode ends),
    and r_t / sqrt(Var[R] + eps) is what the learner sees (Engstrom et al. 2020).

    Args:
        n_envs: Number of parallel environments.
        gamma: Discount of the tracked return.
        clip: Bound of the scaled rewards.
        eps: Added to the variance.
    """

    def __init__(self, n_envs: int, gamma: float, clip: float = 10.0, eps: float = 1e-8) -> None:
        self.rms = RunningMeanStd(())
        self.ret = np.zeros(n_envs)
        self.gamma, self.clip, self.eps = gamma, clip, eps

    def __call__(self, rewards: NDArray[Any], dones: NDArray[np.bool_]) -> NDArray[np.float32]:
        """Scale one vector step of rewards and update the statistics."""
        self.ret = self.ret * self.gamma + rewards
        self.rms.update(self.ret)
        self.ret[dones] = 0.0
        return np.clip(rewards / np.sqrt(self.rms.var + self.eps), -self.clip, self.clip).astype(
            np.float32
        )
