"""Argument checks shared by the planning functions (gamma, values, policies, q)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from policylab import validation
from policylab.exceptions import (
    InvalidArgumentError,
    InvalidPolicyError,
    ShapeError,
)
from policylab.mdp.policy import Policy

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "PolicyLike",
    "as_policy",
    "check_gamma",
    "check_positive_int",
    "check_q",
    "check_tol",
    "check_v",
    "labels_of",
    "raise_if_stuck",
    "require_terminal_reachable",
    "states_not_reaching_terminal",
]

PolicyLike = Policy | Mapping[Any, Any] | Any
"""A :class:`Policy`, an (S, A) array of probabilities, (S,) action indices, or a
``{state: action}`` / ``{state: {action: prob}}`` mapping of labels."""


def check_gamma(mdp: FiniteMDP, gamma: float | None) -> float:
    """The discount rate to use: ``gamma`` if given (checked to lie in [0, 1]), else the MDP's."""
    return validation.check_gamma(gamma, mdp.gamma)


def check_tol(tol: float, name: str = "tol") -> float:
    """A strictly positive finite tolerance."""
    return validation.check_positive(tol, name)


def check_positive_int(x: int, name: str, minimum: int = 1) -> int:
    """An integer >= ``minimum`` (bools rejected): :func:`policylab.validation.check_count`."""
    return validation.check_count(x, name, minimum)


def check_v(mdp: FiniteMDP, v: ArrayLike, name: str = "v") -> NDArray[np.float64]:
    """A state-value vector of shape (S,), finite, as float64 (terminal entries must be 0)."""
    arr = np.asarray(v, dtype=np.float64)
    if arr.shape != (mdp.n_states,):
        raise ShapeError(
            f"{name} has shape {arr.shape}; expected (S,) = ({mdp.n_states},), one value per "
            f"state of MDP {mdp.name!r}"
        )
    if not np.all(np.isfinite(arr)):
        s = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidArgumentError(f"{name}[{mdp.states[s]!r}] = {arr[s]!r}; values must be finite")
    return arr


def check_q(mdp: FiniteMDP, q: ArrayLike) -> NDArray[np.float64]:
    """An action-value array of shape (S, A) with finite entries on available actions."""
    arr = np.asarray(q, dtype=np.float64)
    if arr.shape != (mdp.n_states, mdp.n_actions):
        raise ShapeError(
            f"q has shape {arr.shape}; expected (S, A) = ({mdp.n_states}, {mdp.n_actions}) for "
            f"MDP {mdp.name!r}"
        )
    bad = mdp.action_mask & ~np.isfinite(arr)
    if np.any(bad):
        s, a = map(int, np.argwhere(bad)[0])
        raise InvalidArgumentError(
            f"q({mdp.states[s]!r}, {mdp.actions[a]!r}) = {arr[s, a]!r}; action values of "
            "available actions must be finite"
        )
    return arr


def as_policy(mdp: FiniteMDP, policy: PolicyLike) -> Policy:
    """Turn any accepted policy form into a :class:`Policy` of ``mdp``.

    Raises:
        InvalidPolicyError: If the policy was built for another MDP or is malformed.
    """
    if isinstance(policy, Policy):
        if policy.states != mdp.states or policy.actions != mdp.actions:
            raise InvalidPolicyError(
                f"the policy was built for another MDP ({len(policy.states)} states, actions "
                f"{list(policy.actions)[:8]!r}); MDP {mdp.name!r} has {mdp.n_states} states and "
                f"actions {list(mdp.actions)[:8]!r}"
            )
        return policy
    if isinstance(policy, Mapping):
        rows = list(policy.values())
        if rows and all(isinstance(r, Mapping) for r in rows):
            return Policy.stochastic(mdp, policy)
        return Policy.deterministic(mdp, policy)
    arr = np.asarray(policy)
    if arr.ndim == 1 and np.issubdtype(arr.dtype, np.integer):
        return Policy.from_actions(mdp, arr)
    if arr.ndim == 2:
        return Policy.from_array(mdp, arr.astype(np.float64))
    raise InvalidPolicyError(
        f"a policy must be a Policy, an (S, A) = ({mdp.n_states}, {mdp.n_actions}) array of "
        f"probabilities, (S,) action indices or a mapping of labels; got "
        f"{type(policy).__name__} with shape {arr.shape}"
    )


def states_not_reaching_terminal(mdp: FiniteMDP, graph: sp.csr_array) -> NDArray[np.int64]:
    """Indices of non-terminal states from which no terminal state can be reached.

    ``graph`` is an S x S sparse matrix whose nonzeros are the possible moves s -> s'
    (p(s' | s, pi(s)) for one policy, or the union over actions). In a finite Markov
    chain a terminal state is reached with probability 1 from s exactly when it is
    reachable with positive probability from every state reachable from s, i.e. from
    every state of the chain; so the states returned here are the ones whose value
    diverges (or is undefined) at gamma = 1.
    """
    S = mdp.n_states
    if not mdp.terminal.any():
        return np.flatnonzero(~mdp.terminal).astype(np.int64)
    # Reverse edges s' -> s, plus a virtual source S linked to every terminal state.
    g = sp.coo_array(graph)
    keep = g.data > 0
    rows = np.concatenate([g.col[keep], np.full(int(mdp.terminal.sum()), S)])
    cols = np.concatenate([g.row[keep], np.flatnonzero(mdp.terminal)])
    rev = sp.csr_array((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(S + 1, S + 1))
    reached = breadth_first_order(rev, S, directed=True, return_predecessors=False)
    ok = np.zeros(S + 1, dtype=bool)
    ok[reached] = True
    return np.flatnonzero(~ok[:S] & ~mdp.terminal).astype(np.int64)


def labels_of(mdp: FiniteMDP, idx: NDArray[np.int64], limit: int = 8) -> str:
    """A short list of state labels for messages."""
    labs = [repr(mdp.states[int(i)]) for i in idx[:limit]]
    more = f" ... ({len(idx)} in all)" if len(idx) > limit else ""
    return "[" + ", ".join(labs) + more + "]"


def require_terminal_reachable(
    mdp: FiniteMDP, graph: sp.csr_array, what: str, error: type[ValueError] = InvalidPolicyError
) -> None:
    """Raise ``error`` if some state cannot reach a terminal state in ``graph`` (gamma = 1)."""
    raise_if_stuck(mdp, states_not_reaching_terminal(mdp, graph), what, error)


def raise_if_stuck(
    mdp: FiniteMDP, bad: NDArray[np.int64], what: str, error: type[ValueError] = InvalidPolicyError
) -> None:
    """Raise ``error`` naming the states ``bad`` that never reach a terminal state (gamma = 1)."""
    if len(bad):
        hint = (
            "the MDP has no terminal state (a continuing task)"
            if not mdp.terminal.any()
            else "no terminal state is reached from these states"
        )
        raise error(
            f"with gamma = 1 the value of {what} is undefined: {hint}: "
            f"{labels_of(mdp, bad)}. Use gamma < 1, a policy that reaches a terminal state "
            "with probability 1, or relative_value_iteration for average reward"
        )
