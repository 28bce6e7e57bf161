"""Value, policy and modified policy iteration on a :class:`~policylab.mdp.PostDecisionMDP`.

With p(s' | s, a) = K(s' | f(s, a)), the action values are

    q(s, a) = r(s, a) + gamma W(f(s, a)),    W = K v  (W(y) = E[v(S') | y]),

so a Bellman optimality backup (T v)(s) = max_{a in A(s)} q(s, a) costs one product
K v (over the post-decision states, once, whatever the number of actions) and one
compiled pass over the (S, A) arrays that takes the maximum as it goes (no (S, A)
temporary), where the outcome table of the same MDP would be read entry by entry
for every (s, a, s'). A policy's backup (T_pi v)(s) = r(s, pi(s)) + gamma W(f(s, pi(s)))
costs the same product and an S-long gather.

The solvers keep the proofs of accuracy of their tabular counterparts in
:mod:`policylab.planning.control`: value and modified policy iteration stop on
MacQueen's bounds (max_s |v(s) - v_*(s)| <= tol), and policy iteration reports the
bound of its last evaluation, ||r_pi + gamma P_pi v - v||_inf / (1 - gamma). On the same
MDP as a :class:`~policylab.mdp.FiniteMDP` (:meth:`~policylab.mdp.PostDecisionMDP.to_finite_mdp`)
they return the same v_*, greedy policy and bounds up to rounding.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numba import njit, prange

from policylab.exceptions import InvalidArgumentError, NotConvergedWarning
from policylab.planning._checks import check_positive_int, check_tol, check_v
from policylab.planning._kernels import (
    _parallel,
    _row_dots,
    _row_dots_par,
    component_solver_name,
    dense_block_max,
    small_components,
    solve_by_components,
)
from policylab.planning._sweeps import run_sweeps
from policylab.planning.bellman import DEFAULT_TIE_TOL, greedy_policy
from policylab.planning.result import PlanningResult

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.postdecision import PostDecisionMDP

__all__ = [
    "DENSE_EVAL_MAX_STATES",
    "choose_method",
    "evaluate_actions",
    "modified_policy_iteration",
    "optimality_backup",
    "policy_iteration",
    "q_values",
    "value_iteration",
]

#: Policy iteration evaluates a policy with a dense LU up to this many states, with
#: GMRES on the operator v -> v - gamma P_pi v above.
DENSE_EVAL_MAX_STATES = 3000


@njit(cache=True, nogil=True, inline="always")
def _backup_state(
    post: Any, R: Any, gamma: float, w: Any, out: Any, act: Any, s: Any
) -> None:  # pragma: no cover
    # out[s] = max_a R[s, a] + gamma w[post[s, a]], act[s] the first argmax (R is -inf
    # on unavailable actions, whose post entry is 0).
    best = -np.inf
    best_a = 0
    for a in range(post.shape[1]):
        q = R[s, a] + gamma * w[post[s, a]]
        if q > best:
            best = q
            best_a = a
    out[s] = best
    act[s] = best_a


@njit(cache=True, nogil=True)
def _backup(
    post: Any, R: Any, gamma: float, w: Any, out: Any, act: Any
) -> None:  # pragma: no cover
    for s in range(post.shape[0]):
        _backup_state(post, R, gamma, w, out, act, s)


@njit(cache=True, nogil=True, parallel=True)
def _backup_par(
    post: Any, R: Any, gamma: float, w: Any, out: Any, act: Any
) -> None:  # pragma: no cover
    for s in prange(post.shape[0]):
        _backup_state(post, R, gamma, w, out, act, s)


def _masked(model: PostDecisionMDP) -> NDArray[np.float64]:
    """r(s, a) with -inf on unavailable actions (cached on the model)."""
    cached: NDArray[np.float64] | None = model.__dict__.get("_masked_reward")
    if cached is None:
        cached = np.ascontiguousarray(np.where(model.action_mask, model.reward, -np.inf))
        model.__dict__["_masked_reward"] = cached
    return cached


def _expect(model: PostDecisionMDP, v: NDArray[np.float64]) -> NDArray[np.float64]:
    """W = K v, (K v)(y) = sum_s' K(s' | y) v(s') (see :meth:`PostDecisionKernel.expect`).

    A kernel that is one sparse matrix is multiplied by the compiled row sums of the
    planning kernels (the same sums in the same order as SciPy's product, split over
    numba's threads on large kernels); other kernels by their own ``expect``.
    """
    x = np.ascontiguousarray(v, dtype=np.float64)
    k = model.kernel.factors[0]
    if len(model.kernel.factors) != 1 or not sp.issparse(k):
        return model.kernel.expect(x)
    w = np.empty(k.shape[0])
    dots = _row_dots_par if _parallel(k.nnz) else _row_dots
    dots(k.indptr, k.indices, k.data, x, w)
    return w


def optimality_backup(
    model: PostDecisionMDP, gamma: float, v: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """(T v)(s) = max_{a in A(s)} r(s, a) + gamma (K v)(f(s, a)), and the first argmax a.

    One product W = K v, then one compiled pass over the (S, A) arrays (split over
    numba's threads on large models; each state's maximum is the same either way).
    """
    w = _expect(model, v)
    out = np.empty(model.n_states)
    act = np.empty(model.n_states, dtype=np.int64)
    kernel = _backup_par if _parallel(model.post.size) else _backup
    kernel(model.post, _masked(model), gamma, w, out, act)
    return out, act


def q_values(
    model: PostDecisionMDP,
    v: NDArray[np.float64],
    gamma: float,
    *,
    w: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """q(s, a) = r(s, a) + gamma (K v)(f(s, a)), -inf where a is not in A(s); (S, A).

    ``w`` is the product K v when the caller has it already.
    """
    w = _expect(model, v) if w is None else w
    q = w[model.post]  # one (S, A) array, updated in place
    q *= gamma
    q += _masked(model)
    return q


def _policy_parts(
    model: PostDecisionMDP, actions: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    rows = np.arange(model.n_states)
    return model.reward[rows, actions], model.post[rows, actions]


def _check_gamma(model: PostDecisionMDP, gamma: float | None) -> float:
    from policylab.planning._checks import check_gamma

    g = check_gamma(model, gamma)  # type: ignore[arg-type]
    if g >= 1.0:
        raise InvalidArgumentError(
            f"gamma = {g:g} on {model.name!r}: a post-decision MDP is a continuing task (no "
            "terminal states), so its solvers need gamma < 1"
        )
    return g


def _by_components(
    model: PostDecisionMDP, y_pi: NDArray[np.int64], r_pi: NDArray[np.float64], gamma: float
) -> tuple[NDArray[np.float64], int] | None:
    """v_pi by strongly connected components of the policy's graph (rows K(. | y_pi(s))).

    Only for a kernel that is one sparse matrix; None otherwise, or when a component is
    too large for its dense LU (see :func:`~policylab.planning._kernels.solve_by_components`).
    """
    kernel = model.kernel.factors[0]
    if len(model.kernel.factors) != 1 or not sp.issparse(kernel):
        return None
    return solve_by_components(
        kernel.indptr,
        kernel.indices,
        kernel.data,
        y_pi,
        r_pi,
        gamma,
        dense_block_max(model.nbytes),
    )


def evaluate_actions(
    model: PostDecisionMDP,
    actions: NDArray[np.int64],
    gamma: float,
    *,
    tol: float | None = None,
    x0: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """v_pi of a deterministic policy: the solution of v = r_pi + gamma P_pi v, P_pi = K[f(., pi)].

    With a kernel that is one sparse matrix, one strongly connected component of the
    policy's graph at a time when each is small (back-substitution, and a dense LU per
    component whose matrix is no larger than the model:
    :func:`~policylab.planning._kernels.solve_by_components`); otherwise a dense LU up
    to :data:`DENSE_EVAL_MAX_STATES` states (the rows K(. | f(s, pi(s))) formed), GMRES
    on the operator v -> v - gamma (K v)(f(., pi)) above, to a residual of ``tol`` (1 -
    gamma) (default 1e-10 times the value scale max|r| / (1 - gamma)).

    Returns:
        v and an info dict: ``solver``, ``residual`` (||r_pi + gamma P_pi v - v||_inf) and
        ``error_bound`` = residual / (1 - gamma) >= max_s |v(s) - v_pi(s)|.
    """
    v, info, _ = _evaluate(model, actions, gamma, tol=tol, x0=x0)
    return v, info


def _evaluate(
    model: PostDecisionMDP,
    actions: NDArray[np.int64],
    gamma: float,
    *,
    tol: float | None = None,
    x0: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], dict[str, Any], NDArray[np.float64]]:
    """:func:`evaluate_actions`, and the product K v_pi that its residual took.

    Policy iteration's improvement reuses that product.
    """
    r_pi, y_pi = _policy_parts(model, actions)
    S = model.n_states
    info: dict[str, Any] = {}
    found = _by_components(model, y_pi, r_pi, gamma)
    if found is not None:
        v, largest = found
        info["solver"] = component_solver_name(largest, S)
    elif S <= DENSE_EVAL_MAX_STATES:
        M = -gamma * model.kernel.dense_rows(y_pi)
        M[np.arange(S), np.arange(S)] += 1.0
        v = np.asarray(np.linalg.solve(M, r_pi), dtype=np.float64)
        info["solver"] = "dense LU"
    else:
        from policylab.planning.evaluation import KRYLOV_RTOL, _gmres_refined

        def matvec(x: NDArray[np.float64]) -> NDArray[np.float64]:
            x = np.asarray(x, dtype=np.float64).reshape(-1)
            return np.asarray(x - gamma * _expect(model, x)[y_pi])

        op = spla.LinearOperator((S, S), matvec=matvec, dtype=np.float64)
        scale = max(1.0, float(np.abs(r_pi).max(initial=0.0))) / (1.0 - gamma)
        target = (KRYLOV_RTOL * scale if tol is None else tol) * (1.0 - gamma)
        v, its, _ = _gmres_refined(op, r_pi, x0, target)
        info["solver"] = "GMRES"
        info["krylov_iterations"] = its
    w = _expect(model, v)
    res = float(np.abs(r_pi + gamma * w[y_pi] - v).max(initial=0.0))
    info["residual"] = res
    info["error_bound"] = res / (1.0 - gamma)
    return v, info, w


def _result(
    model: PostDecisionMDP,
    v: NDArray[np.float64],
    gamma: float,
    tie_tol: float,
    **fields: Any,
) -> PlanningResult:
    q = q_values(model, v, gamma)
    return PlanningResult(
        v=v,
        q=q,
        policy=greedy_policy(model, q, tie_tol),  # type: ignore[arg-type]
        gamma=gamma,
        **fields,
    )


def value_iteration(
    model: PostDecisionMDP,
    *,
    tol: float = 1e-8,
    gamma: float | None = None,
    max_iter: int = 100_000,
    v0: ArrayLike | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Value iteration v_{k+1} = T v_k with :func:`optimality_backup`, stopped by MacQueen's bounds.

    The same rule as :func:`policylab.planning.value_iteration`: the midpoint of the bounds
    is returned once they pin v_* down to within ``tol``, so max_s |v(s) - v_*(s)| <=
    ``error_bound`` <= ``tol``.
    """
    t0 = time.perf_counter()
    g = _check_gamma(model, gamma)
    t = check_tol(tol)
    check_positive_int(max_iter, "max_iter")
    start = np.zeros(model.n_states) if v0 is None else check_v(model, v0, "v0").copy()  # type: ignore[arg-type]

    def sync(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return optimality_backup(model, g, v)[0]

    out = run_sweeps(
        synchronous=sync,
        in_place=None,
        v0=start,
        live=np.ones(model.n_states, dtype=bool),
        gamma=g,
        tol=t,
        max_iter=max_iter,
        what="value iteration",
    )
    return _result(
        model,
        out.v,
        g,
        tie_tol,
        iterations=out.iterations,
        converged=out.converged,
        history=out.history,
        method="value iteration (post-decision)",
        residual=out.residual,
        error_bound=out.error_bound,
        seconds=time.perf_counter() - t0,
    )


def modified_policy_iteration(
    model: PostDecisionMDP,
    *,
    m: int | str = "adaptive",
    tol: float = 1e-8,
    gamma: float | None = None,
    max_iter: int = 100_000,
    v0: ArrayLike | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Modified policy iteration v_{k+1} = T_{pi_k}^m T v_k, stopped by MacQueen's bounds.

    The bounds are those of d = T v_k - v_k, whatever m was.

    The rules of :func:`policylab.planning.modified_policy_iteration`, adaptive m
    included (the evaluation sweeps go on while the span of their change shrinks and
    exceeds a tenth of the improvement's residual span), with both backups computed
    through W = K v.
    """
    from policylab.planning.control import mpi_arguments, mpi_iterations

    t0 = time.perf_counter()
    g = _check_gamma(model, gamma)
    t, m_sweeps = mpi_arguments(tol, max_iter, m)
    start = np.zeros(model.n_states) if v0 is None else check_v(model, v0, "v0").copy()  # type: ignore[arg-type]

    def policy_backup(
        act: NDArray[np.int64],
    ) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
        r_pi, y_pi = _policy_parts(model, act)
        return lambda x: r_pi + g * _expect(model, x)[y_pi]

    v, history, sweeps, converged, bound, residual = mpi_iterations(
        lambda x: optimality_backup(model, g, x),
        policy_backup,
        start,
        np.ones(model.n_states, dtype=bool),
        g,
        t,
        max_iter,
        m_sweeps,
    )
    if not converged:
        warnings.warn(
            f"modified policy iteration stopped after {len(history)} improvements (max_iter): "
            f"last change {residual:.3g} > tol {t:g}",
            NotConvergedWarning,
            stacklevel=2,
        )
    return _result(
        model,
        v,
        g,
        tie_tol,
        iterations=len(history),
        converged=converged,
        history=np.asarray(history),
        method=f"modified policy iteration (post-decision, m={m})",
        residual=residual,
        error_bound=bound,
        seconds=time.perf_counter() - t0,
        info={"evaluation_sweeps": sweeps} if m_sweeps is None else {},
    )


def policy_iteration(
    model: PostDecisionMDP,
    *,
    gamma: float | None = None,
    max_iter: int = 1000,
    tol: float | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Policy iteration with exact evaluation (:func:`evaluate_actions`) and greedy improvement.

    Starts from the policy greedy in r(s, a); keeps pi_k(s) whenever it is within
    ``tie_tol`` of the best action, as :func:`policylab.planning.policy_iteration` does,
    and stops when no state changes its action. ``error_bound`` is the last
    evaluation's, which bounds max_s |v(s) - v_*(s)| once the policy is stable.
    """
    t0 = time.perf_counter()
    g = _check_gamma(model, gamma)
    check_positive_int(max_iter, "max_iter")
    eval_tol = None if tol is None else check_tol(tol)
    S = model.n_states
    rows = np.arange(S)
    current = _masked(model).argmax(axis=1).astype(np.int64)
    v: NDArray[np.float64] | None = None
    q: NDArray[np.float64] | None = None
    history: list[float] = []
    converged = False
    info: dict[str, Any] = {}
    for _ in range(max_iter):
        v, info, w = _evaluate(model, current, g, tol=eval_tol, x0=v)
        q = q_values(model, v, g, w=w)
        best_a = q.argmax(axis=1)
        best = q[rows, best_a]
        keep = q[rows, current] >= best - tie_tol * np.maximum(1.0, np.abs(best))
        new = np.where(keep, current, best_a)
        changed = int(np.count_nonzero(new != current))
        history.append(changed)
        current = new
        if changed == 0:
            converged = True
            break
    assert v is not None and q is not None
    if not converged:
        warnings.warn(
            f"policy iteration stopped after {len(history)} improvements (max_iter) with "
            f"{history[-1]:g} states still changing",
            NotConvergedWarning,
            stacklevel=2,
        )
    from policylab.mdp.policy import Policy

    return PlanningResult(
        v=v,
        q=q,
        policy=Policy.from_actions(model, current),  # type: ignore[arg-type]
        iterations=len(history),
        converged=converged,
        history=np.asarray(history, dtype=np.float64),
        method="policy iteration (post-decision, exact)",
        gamma=g,
        residual=float(info["residual"]),
        error_bound=float(info["error_bound"]),
        seconds=time.perf_counter() - t0,
        info=dict(info),
    )


def choose_method(model: PostDecisionMDP, gamma: float | None = None) -> tuple[str, str]:
    """The method ``solve(model, method="auto")`` uses on a post-decision MDP, and why."""
    g = _check_gamma(model, gamma)
    kernel = model.kernel.factors[0]
    if len(model.kernel.factors) == 1 and sp.issparse(kernel):
        first = _masked(model).argmax(axis=1).astype(np.int64)  # policy iteration's start
        largest = small_components(
            kernel.indptr,
            kernel.indices,
            kernel.data,
            _policy_parts(model, first)[1],
            model.nbytes,
        )
        if largest is not None:
            return "pi", (
                f"post-decision model with one sparse kernel ({model.n_states:,} states) "
                "whose first policy's graph splits into small strongly connected components "
                f"(at most {largest:,} states): each exact evaluation is a back-substitution "
                "with small dense LUs, so policy iteration needs a handful of cheap evaluations"
            )
    return "mpi", (
        f"post-decision model ({model.n_states:,} states, {model.n_post:,} post-decision "
        f"states, gamma {g:g}): each backup is one product K v plus an (S, A) maximum, and "
        "policy sweeps cost nearly as much, so modified policy iteration (adaptive m) "
        "replaces the linear solves of policy iteration"
    )
