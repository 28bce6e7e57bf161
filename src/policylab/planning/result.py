"""The one result type returned by every planning solver."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = ["PlanningResult"]


@dataclass(frozen=True, eq=False)
class PlanningResult:
    """What a planning solver found, and how.

    Attributes:
        v: State values (S,): v_* for the optimal-control solvers, v_pi for policy
            evaluation, the relative values h for average reward, v_0 for a finite
            horizon.
        q: Action values (S, A) from ``v`` (q = r + gamma P v; -inf on unavailable
            actions).
        policy: The greedy (optimal) policy, or the evaluated policy.
        iterations: Sweeps (value iteration, evaluation), improvement steps (policy
            iteration), simplex/IPM iterations (linear programming) or stages (finite
            horizon).
        converged: Whether the stopping rule was met before ``max_iter``.
        history: One number per iteration: the sup-norm residual max_s |v_{k+1}(s) -
            v_k(s)| for sweeping methods; the number of states whose action changed
            for policy iteration.
        method: Which solver produced the result.
        gamma: The discount rate used.
        residual: The last sup-norm change max_s |v_{k+1}(s) - v_k(s)| (or the
            linear-solve residual for exact evaluation).
        error_bound: A proven bound on max_s |v(s) - v_target(s)| where the solver has
            one (gamma < 1); None where no bound is known (gamma = 1 sweeps).
        seconds: Wall-clock time of the solve.
        gain: Average reward per step (relative value iteration only).
        stage_values: v_t for t = 0..H, shape (H + 1, S) (finite horizon only).
        stage_actions: Optimal action index per stage and state, shape (H, S); -1 on
            terminal states (finite horizon only).
        info: Solver-specific extras (linear solver used, LP status, ...).
    """

    v: NDArray[np.float64]
    q: NDArray[np.float64]
    policy: Policy
    iterations: int
    converged: bool
    history: NDArray[np.float64]
    method: str
    gamma: float
    residual: float = 0.0
    error_bound: float | None = None
    seconds: float = 0.0
    gain: float | None = None
    stage_values: NDArray[np.float64] | None = None
    stage_actions: NDArray[np.int64] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def optimal_actions(
        self, mdp: FiniteMDP, tol: float = 1e-9, *, proper: bool = False
    ) -> dict[Any, list[Any]]:
        """All actions of each non-terminal state within ``tol`` of the best q, by label.

        ``proper=True``: only those that lead toward termination (see
        :func:`policylab.planning.optimal_actions`).
        """
        from policylab.planning.bellman import optimal_actions

        mask = optimal_actions(mdp, self.q, tol, proper=proper)
        return {
            mdp.states[s]: [mdp.actions[a] for a in np.flatnonzero(mask[s])]
            for s in np.flatnonzero(~mdp.terminal)
        }

    def value_of(self, mdp: FiniteMDP) -> dict[Any, float]:
        """``{state label: value}``."""
        return {lab: float(x) for lab, x in zip(mdp.states, self.v, strict=True)}

    def __repr__(self) -> str:
        bound = "none" if self.error_bound is None else f"{self.error_bound:.3g}"
        return (
            f"PlanningResult(method={self.method!r}, states={len(self.v)}, "
            f"iterations={self.iterations}, converged={self.converged}, "
            f"residual={self.residual:.3g}, error_bound={bound}, seconds={self.seconds:.3g})"
        )
