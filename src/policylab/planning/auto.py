"""``solve``: one entry point to the exact solvers, with ``method="auto"`` choosing one.

The automatic choice follows what the benchmark suite (``benchmarks/bench_planning.py``)
measured on families of MDPs, from the problem's size, gamma and structure:

1. Episodic with gamma < 1 (terminal states that every state can reach): in-place
   (Gauss-Seidel) value iteration, sweeping the states from the terminal states
   backwards and starting from a lower bound of v_*, with each self-loop solved
   exactly. Values then flow to the start in a few sweeps where synchronous sweeps
   need one per step of the longest episode; the stopping rule keeps its proof
   (max_s |v(s) - v_*(s)| <= tol).
2. Episodic with gamma = 1: policy iteration from a proper policy. Sweeps have no
   error bound at gamma = 1 and may need as many sweeps as the longest episode;
   policy iteration is exact and, from a policy that heads for the end, needs few
   improvements.
3. Continuing, whose distributions p(. | s, a) repeat across many (s, a) (the
   distinct rows hold at most half the outcomes, as in inventories and Jack's car
   rental, whose next state depends on the stock after the order or the move):
   policy iteration if the first policy's graph (greedy in r(s, a)) splits into small
   strongly connected components (an inventory reorders only at low stock, and above
   that the stock only falls), whose exact evaluation is then a back-substitution
   between the components with a small dense LU for each ("small": the largest
   component's dense LU costs no more than one pass over the policy's rows).
   Otherwise modified policy iteration with adaptive m: a Bellman optimality sweep
   then costs about what one policy-evaluation sweep does (each distinct row is summed
   once), so cheap sweeps beat the linear solves of policy iteration.
4. Continuing and small otherwise (at most ``DIRECT_MAX_STATES`` states): policy
   iteration (exact evaluation: a dense LU where the dense matrix is no larger than
   the model, else a sparse LU; a handful of improvements).
5. Continuing and large, gamma <= 0.99: synchronous value iteration stopped by
   MacQueen's bounds, which close in a few dozen sweeps on chains that mix.
6. Continuing and large, gamma > 0.99: modified policy iteration with adaptive m
   (partial evaluations carry values further per improvement than single sweeps).

On a :class:`~policylab.mdp.PostDecisionMDP` (a continuing task, gamma < 1):

1. A kernel that is one sparse matrix, and a first policy (greedy in r(s, a)) whose
   graph splits into small strongly connected components (as in rule 3 above: an
   inventory): policy iteration, whose exact evaluation is then a back-substitution between the
   components with a small dense LU for each (no sweeps, no fill-in).
2. Otherwise modified policy iteration with adaptive m: a Bellman optimality backup
   there costs one product K v and an (S, A) maximum, a policy's backup the same
   product and an S-long gather, so improvements cost about what evaluation sweeps do
   and the linear solves of policy iteration (GMRES on the same products) do not pay.

``"mpi"`` is modified policy iteration with adaptive m (see
:func:`~policylab.planning.modified_policy_iteration`).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.postdecision import PostDecisionMDP
from policylab.planning._checks import check_gamma, check_tol
from policylab.planning._kernels import shared_rows, small_components
from policylab.planning.control import (
    _all_reach_terminal,
    modified_policy_iteration,
    policy_iteration,
    value_iteration,
)
from policylab.planning.evaluation import DIRECT_MAX_STATES
from policylab.planning.result import PlanningResult
from policylab.planning.special import linear_programming

if TYPE_CHECKING:
    from policylab.mdp.finite import FiniteMDP

__all__ = ["METHODS", "choose_method", "solve"]

#: The methods of :func:`solve`, by name.
METHODS = {
    "auto": "chosen from the problem's size, gamma and structure",
    "vi": "value iteration (synchronous, MacQueen's bounds)",
    "vi-gs": "value iteration (Gauss-Seidel, terminal states first)",
    "pi": "policy iteration (exact evaluation)",
    "mpi": "modified policy iteration (adaptive m)",
    "lp": "linear programming (HiGHS)",
}


def choose_method(mdp: FiniteMDP | PostDecisionMDP, gamma: float | None = None) -> tuple[str, str]:
    """The method ``solve(mdp, method="auto")`` uses, and why (see the module docstring).

    Returns:
        ``(method, reason)``: a key of :data:`METHODS` other than ``"auto"``, and one
        sentence saying why it suits this MDP.
    """
    if isinstance(mdp, PostDecisionMDP):
        from policylab.planning import postdecision

        return postdecision.choose_method(mdp, gamma)
    g = check_gamma(mdp, gamma)
    n_live = int((~mdp.terminal).sum())
    if mdp.terminal.any() and _all_reach_terminal(mdp):
        if g < 1.0:
            return "vi-gs", (
                "episodic task with gamma < 1: in-place sweeps ordered from the terminal "
                "states backwards carry the values to every state in a few sweeps"
            )
        return "pi", (
            "episodic task with gamma = 1: sweeps have no error bound there; policy "
            "iteration from a proper policy is exact in few improvements"
        )
    shared = shared_rows(mdp)
    if shared is not None:
        first = np.where(mdp.action_mask, mdp.expected_reward, -np.inf).argmax(axis=1)
        row_of = np.arange(mdp.n_states, dtype=np.int64) * mdp.n_actions + first
        row_of[mdp.terminal] = -1
        largest = small_components(mdp.indptr, mdp.next_states, mdp.probs, row_of, mdp.nbytes)
        if largest is not None:
            return "pi", (
                f"continuing task whose first policy's graph splits into small strongly "
                f"connected components (at most {largest:,} states): each exact evaluation "
                "is a back-substitution with small dense LUs, so policy iteration needs a "
                "handful of cheap evaluations"
            )
        n_rows = shared.indptr.shape[0] - 1
        return "mpi", (
            f"continuing task whose {mdp.n_states * mdp.n_actions:,} (state, action) slots "
            f"share {n_rows:,} distinct next-state distributions: each sweep sums those "
            "once, so cheap sweeps (modified policy iteration, adaptive m) replace linear "
            "solves"
        )
    if n_live <= DIRECT_MAX_STATES:
        return "pi", (
            f"continuing task with {n_live:,} states (<= {DIRECT_MAX_STATES:,}): policy "
            "iteration with a sparse LU is exact in a handful of improvements"
        )
    if g <= 0.99:
        return "vi", (
            f"large continuing task, gamma {g:g} <= 0.99: MacQueen's bounds close in a "
            "few dozen synchronous sweeps when the chain mixes"
        )
    return "mpi", (
        f"large continuing task, gamma {g:g} > 0.99: partial policy evaluations (adaptive m) "
        "between improvements carry values further than single sweeps"
    )


def solve(
    mdp: FiniteMDP | PostDecisionMDP,
    method: str = "auto",
    *,
    tol: float = 1e-8,
    gamma: float | None = None,
) -> PlanningResult:
    """v_* and an optimal policy by the named method, or by the one that suits the MDP.

    Args:
        mdp: The MDP.
        method: A key of :data:`METHODS`; ``"auto"`` picks one with :func:`choose_method`.
        tol: Accuracy asked of v for the sweeping methods (proven for gamma < 1; see
            :func:`value_iteration`); policy iteration and linear programming are exact
            up to their own tolerances.
        gamma: Discount rate; default ``mdp.gamma``.

    Returns:
        The solver's :class:`PlanningResult`. With ``"auto"``, ``method`` reads
        ``"auto: <the method used>"`` and ``info["auto"]`` holds ``{"method": key,
        "reason": sentence}``.
    """
    if not isinstance(method, str) or method not in METHODS:
        raise InvalidArgumentError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    g = check_gamma(mdp, gamma)  # type: ignore[arg-type]  # (it reads mdp.gamma only)
    t = check_tol(tol)
    chosen, reason = choose_method(mdp, g) if method == "auto" else (method, "")
    if isinstance(mdp, PostDecisionMDP) and chosen not in ("vi", "pi", "mpi"):
        raise InvalidArgumentError(
            f"method {chosen!r} needs a FiniteMDP's outcome table; a PostDecisionMDP is solved "
            "by 'auto', 'vi', 'pi' or 'mpi' (or solve model.to_finite_mdp())"
        )
    if chosen == "vi":
        res = value_iteration(mdp, tol=t, gamma=g)
    elif chosen == "vi-gs":
        res = value_iteration(mdp, tol=t, gamma=g, gauss_seidel=True, order="auto")
    elif chosen == "mpi":
        res = modified_policy_iteration(mdp, m="adaptive", tol=t, gamma=g)
    elif chosen == "lp" and not isinstance(mdp, PostDecisionMDP):
        res = linear_programming(mdp, gamma=g)
    else:
        res = policy_iteration(mdp, gamma=g)
    if method != "auto":
        return res
    return dataclasses.replace(
        res,
        method=f"auto: {res.method}",
        info={**res.info, "auto": {"method": chosen, "reason": reason}},
    )
