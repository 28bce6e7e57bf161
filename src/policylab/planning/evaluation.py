"""Policy evaluation (notes section 5.2): v_pi from the Bellman expectation equation.

Exact evaluation solves the linear system (I - gamma P_pi) v = r_pi over the
non-terminal states (terminal states have value 0):

* small systems (``solver="direct"``, the default below :data:`DIRECT_MAX_STATES`
  non-terminal states): a sparse LU factorisation (SuperLU), exact to rounding;
* large systems (``solver="krylov"``): restarted GMRES, warm-started where a guess is
  known, with iterative refinement until the residual satisfies
  ||r_pi - (I - gamma P_pi) v||_inf <= (1 - gamma) * tol. Because ||(I - gamma
  P_pi)^{-1}||_inf <= 1 / (1 - gamma) for a (sub)stochastic P_pi, this guarantees
  max_s |v(s) - v_pi(s)| <= tol. A direct LU of a random sparse graph fills in badly
  (it is near-dense at 10^4 states), whereas GMRES needs a few dozen sparse products
  there, since the eigenvalues of such a P_pi other than 1 are small. If GMRES stalls
  the solver falls back to the LU.

With gamma = 1 the system is singular unless the policy reaches a terminal state with
probability 1 from every state; the states from which it does not are named in the
error.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from policylab.exceptions import InvalidArgumentError
from policylab.planning._checks import (
    PolicyLike,
    as_policy,
    check_gamma,
    check_positive_int,
    check_tol,
    check_v,
    require_terminal_reachable,
)
from policylab.planning._kernels import gauss_seidel_expectation_sweep
from policylab.planning._sweeps import run_sweeps
from policylab.planning.bellman import _policy_matrix, _q
from policylab.planning.result import PlanningResult

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = ["DIRECT_MAX_STATES", "evaluate_policy", "solve_policy_system"]

#: Below this many non-terminal states, ``solver="auto"`` uses the sparse LU.
DIRECT_MAX_STATES = 5000

#: Default accuracy of exact evaluation with GMRES, relative to the value scale
#: max|r| / (1 - gamma) (the LU is exact to rounding).
KRYLOV_RTOL = 1e-10


def solve_policy_system(
    mdp: FiniteMDP,
    p_pi: sp.csr_array,
    r_pi: NDArray[np.float64],
    gamma: float,
    *,
    solver: str = "auto",
    tol: float | None = None,
    x0: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Solve v = r_pi + gamma P_pi v on the non-terminal states (v = 0 on terminal states).

    Args:
        mdp: The MDP (for its terminal mask and labels in errors).
        p_pi: P_pi, sparse S x S.
        r_pi: r_pi, (S,).
        gamma: Discount rate.
        solver: ``"auto"``, ``"direct"`` (sparse LU) or ``"krylov"`` (GMRES).
        tol: Sup-norm accuracy for GMRES (default: 1e-10 times the value scale).
        x0: A starting guess for GMRES (S,).

    Returns:
        v (S,) and an info dict (``solver``, ``residual``, ``error_bound``,
        ``krylov_iterations``).

    Raises:
        InvalidPolicyError: With gamma = 1, naming the states from which the policy
            never reaches a terminal state.
    """
    if solver not in ("auto", "direct", "krylov"):
        raise InvalidArgumentError(f"solver must be 'auto', 'direct' or 'krylov'; got {solver!r}")
    if gamma == 1.0:
        require_terminal_reachable(mdp, p_pi, "the policy")
    live = ~mdp.terminal
    S = mdp.n_states
    if live.all():
        P, b = p_pi, r_pi
        idx = None
    else:
        idx = np.flatnonzero(live)
        P = sp.csr_array(p_pi[idx][:, idx])
        b = r_pi[idx]
    n = P.shape[0]
    M = sp.csr_array(sp.eye_array(n, format="csr") - gamma * P)
    v = np.zeros(S)
    info: dict[str, Any] = {}
    use_direct = solver == "direct" or (solver == "auto" and n <= DIRECT_MAX_STATES)
    x: NDArray[np.float64] | None = None
    if not use_direct:
        scale = float(np.abs(b).max(initial=0.0)) / max(1.0 - gamma, 1e-12)
        target_err = tol if tol is not None else KRYLOV_RTOL * max(1.0, scale)
        target_res = target_err * (1.0 - gamma) if gamma < 1.0 else target_err * 1e-3
        guess = None if x0 is None else (x0 if idx is None else x0[idx])
        x, its, res = _gmres_refined(M, b, guess, target_res)
        if res <= target_res:
            info.update(
                solver="krylov (GMRES)",
                krylov_iterations=its,
                residual=res,
                error_bound=res / (1.0 - gamma) if gamma < 1.0 else None,
            )
        else:
            x = None
            info["krylov_fallback"] = f"GMRES stalled at residual {res:.3g}; used sparse LU"
    if x is None:
        x = np.asarray(spla.spsolve(sp.csc_array(M), b), dtype=np.float64)
        res = float(np.abs(b - M @ x).max(initial=0.0))
        info.update(
            solver="direct (sparse LU)",
            residual=res,
            error_bound=res / (1.0 - gamma) if gamma < 1.0 else None,
        )
    if idx is None:
        v[:] = x
    else:
        v[idx] = x
    return v, info


def _gmres_refined(
    M: sp.csr_array, b: NDArray[np.float64], x0: NDArray[np.float64] | None, target: float
) -> tuple[NDArray[np.float64], int, float]:
    """GMRES with iterative refinement until ||b - M x||_inf <= target (or 6 rounds)."""
    x = np.zeros_like(b) if x0 is None else x0.astype(np.float64, copy=True)
    r = b - M @ x
    res = float(np.abs(r).max(initial=0.0))
    its = 0
    for _ in range(6):
        if res <= target:
            break
        count = [0]

        def cb(_: Any, count: list[int] = count) -> None:
            count[0] += 1

        dx, _code = spla.gmres(
            M, r, rtol=1e-8, atol=0.0, restart=40, maxiter=50, callback=cb, callback_type="pr_norm"
        )
        its += count[0]
        x += dx
        r = b - M @ x
        new = float(np.abs(r).max(initial=0.0))
        if not new < res * 0.5:
            res = new
            break
        res = new
    return x, its, res


@overload
def evaluate_policy(
    mdp: FiniteMDP,
    policy: PolicyLike,
    *,
    method: str = ...,
    gamma: float | None = ...,
    tol: float | None = ...,
    max_iter: int = ...,
    in_place: bool = ...,
    solver: str = ...,
    v0: ArrayLike | None = ...,
    return_result: Literal[False] = ...,
) -> NDArray[np.float64]: ...


@overload
def evaluate_policy(
    mdp: FiniteMDP,
    policy: PolicyLike,
    *,
    method: str = ...,
    gamma: float | None = ...,
    tol: float | None = ...,
    max_iter: int = ...,
    in_place: bool = ...,
    solver: str = ...,
    v0: ArrayLike | None = ...,
    return_result: Literal[True],
) -> PlanningResult: ...


def evaluate_policy(
    mdp: FiniteMDP,
    policy: PolicyLike,
    *,
    method: str = "exact",
    gamma: float | None = None,
    tol: float | None = None,
    max_iter: int = 100_000,
    in_place: bool = False,
    solver: str = "auto",
    v0: ArrayLike | None = None,
    return_result: bool = False,
) -> NDArray[np.float64] | PlanningResult:
    """v_pi, the state values of a policy (notes section 5.2, Bellman expectation equation).

    v_pi(s) = sum_a pi(a | s) sum_{s', r} p(s', r | s, a) [r + gamma v_pi(s')],
    with v_pi(s) = 0 on terminal states. In matrix form v_pi = r_pi + gamma P_pi v_pi.

    Args:
        mdp: The MDP.
        policy: A :class:`Policy` (deterministic or stochastic), an (S, A) array, (S,)
            action indices, or a ``{state: action}`` / ``{state: {action: prob}}``
            mapping of labels.
        method: ``"exact"``: a sparse linear solve (see the module docstring for the
            solver and its accuracy); ``"iterative"``: repeated Bellman expectation
            sweeps (iterative policy evaluation, Sutton & Barto section 4.1).
        gamma: Discount rate; default ``mdp.gamma``.
        tol: ``"iterative"``: stop when max_s |v(s) - v_pi(s)| <= tol is proven (gamma
            < 1) or the largest change of a sweep is <= tol (gamma = 1); default 1e-10.
            ``"exact"``: the accuracy asked of GMRES on large systems.
        max_iter: ``"iterative"``: the most sweeps (a NotConvergedWarning if reached).
        in_place: ``"iterative"``: update v state by state within a sweep
            (Gauss-Seidel) instead of synchronously from the previous sweep's values.
        solver: ``"exact"``: ``"auto"``, ``"direct"`` or ``"krylov"``.
        v0: Starting values (iterative sweeps; GMRES warm start); default zeros.
        return_result: Return a :class:`PlanningResult` (values, q, sweeps, history)
            instead of the bare value array.

    Returns:
        v_pi as an (S,) array in the order of ``mdp.states`` (or the full result).

    Raises:
        InvalidPolicyError: If the policy does not fit the MDP, or if gamma = 1 and
            some states never reach a terminal state under the policy (they are named).
    """
    t0 = time.perf_counter()
    pi = as_policy(mdp, policy)
    g = check_gamma(mdp, gamma)
    if method not in ("exact", "iterative"):
        raise InvalidArgumentError(f"method must be 'exact' or 'iterative'; got {method!r}")
    start = np.zeros(mdp.n_states) if v0 is None else check_v(mdp, v0, "v0").copy()
    start[mdp.terminal] = 0.0
    p_pi = _policy_matrix(mdp, pi.probs)
    r_pi = np.einsum("sa,sa->s", pi.probs, mdp.expected_reward)
    if method == "exact":
        v, info = solve_policy_system(
            mdp,
            p_pi,
            r_pi,
            g,
            solver=solver,
            tol=None if tol is None else check_tol(tol),
            x0=start if v0 is not None else None,
        )
        if not return_result:
            return v
        return PlanningResult(
            v=v,
            q=_q(mdp, v, g),
            policy=pi,
            iterations=1,
            converged=True,
            history=np.asarray([info["residual"]]),
            method="evaluate (exact)",
            gamma=g,
            residual=info["residual"],
            error_bound=info["error_bound"],
            seconds=time.perf_counter() - t0,
            info=info,
        )
    t = 1e-10 if tol is None else check_tol(tol)
    check_positive_int(max_iter, "max_iter")
    if g == 1.0:
        require_terminal_reachable(mdp, p_pi, "the policy")
    probs = np.asarray(pi.probs)

    def sync(v: NDArray[np.float64]) -> NDArray[np.float64]:
        out = r_pi + g * (p_pi @ v)
        out[mdp.terminal] = 0.0
        return np.asarray(out)

    def gs(v: NDArray[np.float64]) -> float:
        return gauss_seidel_expectation_sweep(mdp, probs, g, v)

    out = run_sweeps(
        synchronous=None if in_place else sync,
        in_place=gs if in_place else None,
        v0=start,
        live=~mdp.terminal,
        gamma=g,
        tol=t,
        max_iter=max_iter,
        what="iterative policy evaluation" + (" (in place)" if in_place else ""),
    )
    if not return_result:
        return out.v
    return PlanningResult(
        v=out.v,
        q=_q(mdp, out.v, g),
        policy=pi,
        iterations=out.iterations,
        converged=out.converged,
        history=out.history,
        method="evaluate (iterative, " + ("in place" if in_place else "synchronous") + ")",
        gamma=g,
        residual=out.residual,
        error_bound=out.error_bound,
        seconds=time.perf_counter() - t0,
    )
