"""Evaluation of a trained agent: the returns of whole episodes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from policylab.deep.common.envs import EnvLike, make_vec_env
from policylab.exceptions import InvalidArgumentError

__all__ = ["evaluate", "run_episodes"]


class Predictor(Protocol):
    """Anything with ``predict(obs, deterministic=...)`` returning a batch of actions."""

    def predict(self, obs: Any, deterministic: bool = True) -> Any: ...


def _seed_of(seed: int | np.random.Generator | None) -> int | None:
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(2**31 - 1))
    return None if seed is None else int(seed)


def run_episodes(
    act: Callable[[NDArray[Any]], NDArray[Any]],
    env: EnvLike,
    episodes: int,
    seed: int | np.random.Generator | None = 0,
    n_envs: int | None = None,
) -> NDArray[np.float64]:
    """Undiscounted returns of ``episodes`` whole episodes of the policy ``act``.

    ``act`` maps a batch of observations to a batch of actions. Episodes run in a vector
    env (up to 16 at a time); env i runs episodes ``(episodes + i) // n`` times, so the
    count is exact and short episodes are not over-represented.
    """
    if int(episodes) != episodes or episodes < 1:
        raise InvalidArgumentError(f"episodes must be an integer >= 1; got {episodes!r}")
    if n_envs is None:
        n_envs = 1 if not isinstance(env, str) else min(int(episodes), 16)
    venv = make_vec_env(env, n_envs)
    n = venv.num_envs
    targets = np.array([(episodes + i) // n for i in range(n)])
    returns: list[list[float]] = [[] for _ in range(n)]
    ep_ret = np.zeros(n)
    prev_done = np.zeros(n, dtype=bool)
    obs, _ = venv.reset(seed=_seed_of(seed))
    counts = np.zeros(n, dtype=int)
    try:
        while np.any(counts < targets):
            actions = act(obs)
            obs, rew, term, trunc, _ = venv.step(actions)
            live = ~prev_done
            ep_ret[live] += rew[live]
            done = (term | trunc) & live
            for i in np.flatnonzero(done):
                if counts[i] < targets[i]:
                    returns[i].append(float(ep_ret[i]))
                    counts[i] += 1
                ep_ret[i] = 0.0
            prev_done = term | trunc
    finally:
        if venv is not env:
            venv.close()
    return np.array([r for per_env in returns for r in per_env])


def evaluate(
    agent: Predictor,
    env: EnvLike | None = None,
    episodes: int = 10,
    seed: int | np.random.Generator | None = 0,
    deterministic: bool = True,
    n_envs: int | None = None,
) -> NDArray[np.float64]:
    """Per-episode returns of ``agent`` acting on ``env`` (its own env id if None).

    Args:
        agent: A trained agent (or anything with ``predict(obs, deterministic=...)``).
        env: An env id, a Gymnasium env or vector env; None uses the agent's ``env_id``.
        episodes: Number of whole episodes.
        seed: Seed of the evaluation episodes (same seed, same returns).
        deterministic: Greedy (True) or sampled (False) actions.
        n_envs: Episodes run at a time for an env id (default min(episodes, 16)).

    Returns:
        (episodes,) undiscounted episode returns.
    """
    if env is None:
        env = getattr(agent, "env_id", None)
        if env is None:
            raise InvalidArgumentError("the agent has no env id; pass env= to evaluate it")
    return run_episodes(
        lambda o: agent.predict(o, deterministic=deterministic), env, episodes, seed
    )
