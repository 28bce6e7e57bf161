"""Comparing policies (notes section 5.3): the partial order of their value functions."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from policylab.planning._checks import PolicyLike, check_gamma, check_tol
from policylab.planning.evaluation import evaluate_policy

if TYPE_CHECKING:
    from policylab.mdp.finite import FiniteMDP

__all__ = ["compare_policies"]

Comparison = Literal["better", "worse", "equal", "incomparable"]


def compare_policies(
    mdp: FiniteMDP,
    pi1: PolicyLike,
    pi2: PolicyLike,
    *,
    gamma: float | None = None,
    tol: float = 1e-9,
) -> Comparison:
    """Compare two policies by the notes' partial order on policies.

    pi1 >= pi2 if and only if v_pi1(s) >= v_pi2(s) for every state s in S. The answer is
    ``"equal"`` if both hold, ``"better"`` if only pi1 >= pi2, ``"worse"`` if only pi2
    >= pi1, and ``"incomparable"`` if each is better in some state. Values are compared
    with the absolute tolerance ``tol * max(1, |v|)`` and computed exactly
    (:func:`evaluate_policy`).

    Raises:
        InvalidPolicyError: If a policy does not fit the MDP, or its value is undefined
            (gamma = 1 and no terminal state reached).
    """
    g = check_gamma(mdp, gamma)
    t = check_tol(tol)
    v1 = evaluate_policy(mdp, pi1, gamma=g)
    v2 = evaluate_policy(mdp, pi2, gamma=g)
    live = ~mdp.terminal
    slack = t * np.maximum(1.0, np.maximum(np.abs(v1), np.abs(v2)))[live]
    diff = (v1 - v2)[live]
    ge = bool(np.all(diff >= -slack))
    le = bool(np.all(diff <= slack))
    if ge and le:
        return "equal"
    if ge:
        return "better"
    if le:
        return "worse"
    return "incomparable"
