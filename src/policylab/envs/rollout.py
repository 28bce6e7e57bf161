"""Episodes: the sequence S_0, A_0, R_1, S_1, A_1, R_2, ... of one run of a policy."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.mdp.policy import Policy
from policylab.mdp.returns import discounted_return, returns_to_go

__all__ = ["Episode", "rollout"]

Seed = int | np.random.Generator | None


@dataclass(frozen=True)
class Episode:
    """One episode as index arrays, with its labels for display.

    Attributes:
        states: S_0, ..., S_T (T + 1 state indices; S_T is the last state reached).
        actions: A_0, ..., A_{T-1}.
        rewards: R_1, ..., R_T (``rewards[t]`` follows ``actions[t]``).
        terminated: Whether S_T is terminal (the MDP's end: no bootstrap).
        truncated: Whether the episode was cut by a step limit (bootstrap from S_T).
        state_labels: Labels of the state indices (the MDP's order), if known.
        action_labels: Labels of the action indices, if known.
    """

    states: NDArray[np.int64]
    actions: NDArray[np.int64]
    rewards: NDArray[np.float64]
    terminated: bool
    truncated: bool
    state_labels: tuple[Hashable, ...] | None = None
    action_labels: tuple[Hashable, ...] | None = None

    def __len__(self) -> int:
        """T, the number of steps."""
        return len(self.actions)

    def returns(self, gamma: float) -> NDArray[np.float64]:
        """G_0, ..., G_{T-1} (see :func:`~policylab.returns_to_go`)."""
        return returns_to_go(self.rewards, gamma)

    def ret(self, gamma: float) -> float:
        """G_0, the discounted return of the whole episode."""
        return discounted_return(self.rewards, gamma)

    def sequence(self) -> list[Any]:
        """The interleaved sequence [S_0, A_0, R_1, S_1, A_1, R_2, ..., S_T], by label."""
        sl = self.state_labels or tuple(range(int(self.states.max()) + 1))
        al = self.action_labels or tuple(range(int(self.actions.max(initial=0)) + 1))
        out: list[Any] = [sl[self.states[0]]]
        for t in range(len(self)):
            out += [al[self.actions[t]], float(self.rewards[t]), sl[self.states[t + 1]]]
        return out

    def __str__(self) -> str:
        parts = [str(x) for x in self.sequence()]
        end = "terminated" if self.terminated else "truncated" if self.truncated else "stopped"
        return ", ".join(parts) + f"  ({len(self)} steps, {end})"


def rollout(
    env_or_mdp: FiniteMDP | Any,
    policy: Policy | Callable[[Any], int],
    *,
    seed: Seed = None,
    max_steps: int | None = 10_000,
    start: Hashable | None = None,
) -> Episode:
    """Run one episode of a policy in an MDP or a Gymnasium environment.

    Args:
        env_or_mdp: A :class:`FiniteMDP` (simulated directly) or a Gymnasium env with
            discrete observations and actions.
        policy: A :class:`Policy` over the MDP (or over the env's observation indices),
            or a function from observation to action index.
        seed: Seed or generator; the same seed gives the same episode.
        max_steps: Step limit (the episode is then truncated); None for no limit.
        start: Optional start state label (MDP only); default: drawn from the MDP's
            start distribution.

    Returns:
        The :class:`Episode`.
    """
    if max_steps is not None and max_steps <= 0:
        raise InvalidArgumentError(f"max_steps must be positive or None; got {max_steps}")
    rng = np.random.default_rng(seed)
    choose: Callable[[Any], int]
    if isinstance(policy, Policy):
        pol = policy

        def choose(s: Any) -> int:
            return pol.sample(int(s), rng)
    elif callable(policy):
        choose = policy
    else:
        raise InvalidArgumentError(
            f"policy must be a Policy or a callable; got {type(policy).__name__}"
        )
    states: list[int] = []
    actions: list[int] = []
    rewards: list[float] = []
    terminated = truncated = False
    if isinstance(env_or_mdp, FiniteMDP):
        mdp = env_or_mdp
        s = mdp.sample_initial(rng) if start is None else mdp.state_index(start)
        states.append(s)
        labels: tuple[tuple[Hashable, ...] | None, tuple[Hashable, ...] | None] = (
            mdp.states,
            mdp.actions,
        )
        while not mdp.terminal[s]:
            if max_steps is not None and len(actions) >= max_steps:
                truncated = True
                break
            a = int(choose(s))
            s, r, terminated = mdp.step(s, a, rng)
            actions.append(a)
            rewards.append(r)
            states.append(s)
        terminated = bool(mdp.terminal[s])
    else:
        env = env_or_mdp
        env_seed = int(rng.integers(2**31 - 1))
        obs, _ = env.reset(seed=env_seed)
        states.append(int(obs))
        base = getattr(env, "unwrapped", env)
        m = getattr(base, "mdp", None)
        labels = (m.states, m.actions) if isinstance(m, FiniteMDP) else (None, None)
        while True:
            if max_steps is not None and len(actions) >= max_steps:
                truncated = True
                break
            a = int(choose(obs))
            obs, r, term, trunc, _ = env.step(a)
            actions.append(a)
            rewards.append(float(r))
            states.append(int(obs))
            if term or trunc:
                terminated, truncated = bool(term), bool(trunc) and not term
                break
    return Episode(
        np.asarray(states, dtype=np.int64),
        np.asarray(actions, dtype=np.int64),
        np.asarray(rewards, dtype=np.float64),
        terminated,
        truncated,
        labels[0],
        labels[1],
    )
