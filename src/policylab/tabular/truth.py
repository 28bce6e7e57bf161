"""Ground truth for tabular learners: the exact answer and the error of an estimate.

On a problem whose model is known, a learner's estimate is held against the exact
values from :mod:`policylab.planning` (no second solver lives here):

* prediction of a policy pi: v_pi (``evaluate_policy``) and q_pi (``action_values``);
* control: v* and q* (``value_iteration`` to 1e-10).

:meth:`GroundTruth.errors` gives the max and RMS error of V or Q and the share of
non-terminal states whose greedy action (under the estimate Q) is a best action of the
exact action values: for control the optimal actions, for prediction the actions of
the exact policy-improvement step (greedy in q_pi).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from policylab.exceptions import InvalidArgumentError

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = ["GroundTruth", "greedy_probs"]


def greedy_probs(q: NDArray[np.float64], mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The deterministic greedy policy of a Q-table as (S, A) probabilities.

    pi(s) = argmax_a Q(s, a) over A(s), the first best action on exact ties; rows with no
    available action (terminal states) are all zero.
    """
    qm = np.where(mask, q, -np.inf)
    idx = qm.argmax(axis=1)
    out = np.zeros(q.shape, dtype=np.float64)
    live = mask.any(axis=1)
    out[np.flatnonzero(live), idx[live]] = 1.0
    return out


@dataclass(frozen=True)
class GroundTruth:
    """The exact values a learner is scored against.

    Attributes:
        target: ``"v_pi"``, ``"q_pi"`` (prediction) or ``"v*"``, ``"q*"`` (control):
            what the error is measured on.
        v: Exact state values (S,).
        q: Exact action values (S, A).
        best: (S, A) mask of the best actions of ``q`` over A(s).
        mask: A(s), the MDP's action mask.
        live: Non-terminal states.
    """

    target: str
    v: NDArray[np.float64]
    q: NDArray[np.float64]
    best: NDArray[np.bool_]
    mask: NDArray[np.bool_]
    live: NDArray[np.bool_]

    @classmethod
    def prediction(
        cls, mdp: FiniteMDP, policy: Policy, on: Literal["v", "q"] = "q", gamma: float | None = None
    ) -> GroundTruth:
        """v_pi and q_pi of a policy, exact (a linear solve in ``policylab.planning``)."""
        from policylab.planning import action_values, evaluate_policy

        m = mdp if gamma is None else mdp.with_gamma(gamma)
        v = np.asarray(evaluate_policy(m, policy), dtype=np.float64)
        q = np.asarray(action_values(m, v), dtype=np.float64)
        return cls._make(m, "v_pi" if _on(on) == "v" else "q_pi", v, q)

    @classmethod
    def control(
        cls, mdp: FiniteMDP, on: Literal["v", "q"] = "q", gamma: float | None = None
    ) -> GroundTruth:
        """v* and q*, exact (value iteration to 1e-10 in ``policylab.planning``)."""
        from policylab.planning import value_iteration

        m = mdp if gamma is None else mdp.with_gamma(gamma)
        res = value_iteration(m, tol=1e-10)
        return cls._make(
            m,
            "v*" if _on(on) == "v" else "q*",
            np.asarray(res.v, dtype=np.float64),
            np.asarray(res.q, dtype=np.float64),
        )

    @classmethod
    def _make(
        cls, mdp: FiniteMDP, target: str, v: NDArray[np.float64], q: NDArray[np.float64]
    ) -> GroundTruth:
        from policylab.planning import optimal_actions

        mask = np.asarray(mdp.action_mask, dtype=bool)
        q = np.where(mask, q, 0.0)
        live = ~np.asarray(mdp.terminal, dtype=bool)
        return cls(target, v, q, optimal_actions(mdp, q), mask, live)

    def errors(
        self,
        q: NDArray[np.float64] | None,
        v: NDArray[np.float64] | None,
        seen: NDArray[np.bool_] | None = None,
    ) -> tuple[float, float, float]:
        """(max error, RMS error, share of states whose greedy action is best).

        The error is that of V against the exact v (over non-terminal states) when the
        target is a state value, else of Q against the exact q (over the pairs (s, a)
        with a in A(s)). The share is NaN when no Q is given.

        Args:
            q: Estimated Q (S, A), or None.
            v: Estimated V (S,), or None.
            seen: Optional (S,) mask restricting the scores to states seen so far (the
                general Gymnasium path can only score the states it has observed).
        """
        live = self.live if seen is None else self.live & seen
        if self.target.startswith("v"):
            if v is None:
                raise InvalidArgumentError(f"the error on {self.target} needs an estimate of V")
            d = (np.asarray(v) - self.v)[live]
        else:
            if q is None:
                raise InvalidArgumentError(f"the error on {self.target} needs an estimate of Q")
            d = (np.asarray(q) - self.q)[live[:, None] & self.mask]
        e_max = float(np.abs(d).max()) if d.size else 0.0
        e_rms = float(np.sqrt(np.mean(d**2))) if d.size else 0.0
        if q is None:
            return e_max, e_rms, float("nan")
        greedy = np.where(self.mask, q, -np.inf).argmax(axis=1)
        ok = self.best[np.arange(len(greedy)), greedy]
        share = float(ok[live].mean()) if live.any() else 1.0
        return e_max, e_rms, share


def _on(on: str) -> str:
    if on not in ("v", "q"):
        raise InvalidArgumentError(f"the error is measured on 'v' or 'q'; got {on!r}")
    return on
