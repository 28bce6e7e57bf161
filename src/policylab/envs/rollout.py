"""Episodes: the sequence S_0, A_0, R_1, S_1, A_1, R_2, ... of one run of a policy."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import InvalidActionError, InvalidArgumentError, InvalidPolicyError
from policylab.mdp.finite import FiniteMDP
from policylab.mdp.policy import Policy
from policylab.mdp.returns import discounted_return, returns_to_go
from policylab.validation import Seed, as_generator, check_count

__all__ = ["Episode", "rollout"]


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
    if max_steps is not None:
        max_steps = check_count(max_steps, "max_steps (a positive integer or None)")
    rng = as_generator(seed)
    choose: Callable[[Any], int]
    if isinstance(policy, Policy):
        pol = _policy_for(policy, env_or_mdp)

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
            a = _action_index(choose(s), mdp.n_actions)
            s, r, terminated = mdp.step(s, a, rng)
            actions.append(a)
            rewards.append(r)
            states.append(s)
        terminated = bool(mdp.terminal[s])
    else:
        env = env_or_mdp
        if not (hasattr(env, "reset") and hasattr(env, "step")):
            raise InvalidArgumentError(
                f"rollout runs in a FiniteMDP or a Gymnasium env; got {type(env).__name__}"
            )
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
            a = _action_index(choose(obs), None)
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


def _policy_for(policy: Policy, env_or_mdp: Any) -> Policy:
    """The policy, checked to fit the MDP (or the env's MDP, or its Discrete spaces)."""
    if isinstance(env_or_mdp, FiniteMDP):
        return policy.check_fits(env_or_mdp)
    base = getattr(env_or_mdp, "unwrapped", env_or_mdp)
    m = getattr(base, "mdp", None)
    if isinstance(m, FiniteMDP):
        return policy.check_fits(m)
    for space, n, what in (
        (getattr(env_or_mdp, "observation_space", None), len(policy.states), "states"),
        (getattr(env_or_mdp, "action_space", None), len(policy.actions), "actions"),
    ):
        size = getattr(space, "n", None)
        if size is not None and int(size) != n:
            raise InvalidPolicyError(
                f"the policy has {n} {what}; the env's {space} has {int(size)}"
            )
    return policy


def _action_index(a: Any, n_actions: int | None) -> int:
    """The action a policy function returned, as an index (checked where the count is known)."""
    if isinstance(a, bool | np.bool_) or not isinstance(a, int | np.integer):
        raise InvalidActionError(
            f"the policy function must return an action index (an integer); got "
            f"{type(a).__name__} {a!r}"
        )
    if n_actions is not None and not 0 <= int(a) < n_actions:
        raise InvalidActionError(
            f"the policy function returned action index {int(a)}; expected 0..{n_actions - 1}"
        )
    return int(a)
