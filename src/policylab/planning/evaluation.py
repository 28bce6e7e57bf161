"""Policy evaluation (notes section 5.2): v_pi from the Bellman expectation equation.

Exact evaluation solves the linear system (I - gamma P_pi) v = r_pi over the
non-terminal states (terminal states have value 0):

* a deterministic policy whose transitions, self-loops aside, form no cycle
  (``solver="auto"``; proper policies that head for the goal on grids and chains):
  back-substitution in the order that solves each state after its successors, exact
  in one pass with no matrix and no fill-in; with gamma < 1, cycles too, one strongly
  connected component of the policy's graph at a time (a dense LU for each component
  whose dense matrix is no larger than the model, back-substitution between them), as
  in an inventory whose orders cycle only through the low stock levels;
* small systems (``solver="direct"``, the default below :data:`DIRECT_MAX_STATES`
  non-terminal states): a sparse LU factorisation (SuperLU), exact to rounding;
  with ``solver="auto"``, gamma < 1 and a deterministic policy whose dense S x S
  matrix is no larger than the model itself (at most :data:`DENSE_MAX_STATES`
  states, dense rows as in inventories and car rentals), a dense LU (LAPACK) of
  I - gamma P_pi built straight from the outcome table instead;
* large systems (``solver="auto"`` above that size, gamma < 1): synchronous sweeps
  v <- r_pi + gamma P_pi v, warm-started, stopped by MacQueen's bounds (the same rule
  as value iteration) as soon as max_s |v(s) - v_pi(s)| <= tol is proven; the
  default tol is 1e-10 times the value scale max|r| / (1 - gamma). On well-mixing
  chains (random sparse graphs, whose P_pi has small eigenvalues besides 1) the
  error span shrinks by gamma |lambda_2| per sweep, so a few dozen products suffice;
  a direct LU of such a graph fills in badly (near-dense at 10^4 states).
* slowly mixing chains (the sweeps have not finished after 60 products) and gamma =
  1: up to :data:`LU_AFTER_SWEEPS_MAX_STATES` non-terminal states the sparse LU (such
  chains are local, grids and lines, and factor with little fill-in, where
  unpreconditioned GMRES needs thousands of products);
* larger ones, or ``solver="krylov"``: restarted GMRES on the matrix-free operator, with
  iterative refinement until ||r_pi - (I - gamma P_pi) v||_inf <= (1 - gamma) tol,
  which guarantees max_s |v(s) - v_pi(s)| <= tol since ||(I - gamma P_pi)^{-1}||_inf
  <= 1 / (1 - gamma) for a (sub)stochastic P_pi. If GMRES stalls, the sparse LU.

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
from policylab.mdp.postdecision import PostDecisionMDP
from policylab.planning._checks import (
    PolicyLike,
    as_policy,
    check_gamma,
    check_positive_int,
    check_tol,
    check_v,
    require_terminal_reachable,
)
from policylab.planning._kernels import (
    component_policy_solve,
    component_solver_name,
    dense_block_max,
    dense_policy_system,
    gauss_seidel_expectation_sweep,
    policy_matvec,
)
from policylab.planning._sweeps import run_sweeps, span_bounds
from policylab.planning.bellman import _policy_matrix, _q
from policylab.planning.result import PlanningResult

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = ["DENSE_MAX_STATES", "DIRECT_MAX_STATES", "evaluate_policy", "solve_policy_system"]

#: Below this many non-terminal states, ``solver="auto"`` uses the sparse LU.
DIRECT_MAX_STATES = 5000

#: ``solver="auto"``: the most states for a dense LU (when the dense matrix is no
#: larger than the model).
DENSE_MAX_STATES = 3000

#: ``solver="auto"``: up to this many non-terminal states, a system that the sweeps do
#: not finish goes to the sparse LU directly (above it, GMRES first).
LU_AFTER_SWEEPS_MAX_STATES = 250_000

#: Default accuracy of exact evaluation with GMRES, relative to the value scale
#: max|r| / (1 - gamma) (the LU is exact to rounding).
KRYLOV_RTOL = 1e-10


def solve_policy_system(
    mdp: FiniteMDP,
    p_pi: sp.csr_array | None,
    r_pi: NDArray[np.float64],
    gamma: float,
    *,
    solver: str = "auto",
    tol: float | None = None,
    x0: NDArray[np.float64] | None = None,
    actions: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.float64], dict[str, Any]]:
    """Solve v = r_pi + gamma P_pi v, with v = 0 on terminal states.

    The system is written over all states; the rows of terminal states are v(s) = 0
    (P_pi has no entries there), so no submatrix is ever extracted.

    Args:
        mdp: The MDP (for its outcome table, terminal mask and labels in errors).
        p_pi: P_pi, sparse S x S; may be None when ``actions`` is given.
        r_pi: r_pi, (S,).
        gamma: Discount rate.
        solver: ``"auto"``, ``"direct"`` (sparse LU) or ``"krylov"`` (GMRES).
        tol: Sup-norm accuracy for GMRES (default: 1e-10 times the value scale).
        x0: A starting guess for GMRES (S,).
        actions: For a deterministic policy, its action index per state: GMRES then
            multiplies by P_pi straight from the outcome table (no matrix is built).

    Returns:
        v (S,) and an info dict (``solver``, ``residual``, ``error_bound``,
        ``krylov_iterations``).

    Raises:
        InvalidPolicyError: With gamma = 1, naming the states from which the policy
            never reaches a terminal state.
    """
    if solver not in ("auto", "direct", "krylov"):
        raise InvalidArgumentError(f"solver must be 'auto', 'direct' or 'krylov'; got {solver!r}")
    S = mdp.n_states
    if p_pi is None and actions is None:
        raise InvalidArgumentError("solve_policy_system needs p_pi or actions")

    def matrix() -> sp.csr_array:
        if p_pi is not None:
            return p_pi
        assert actions is not None
        w = np.zeros((S, mdp.n_actions))
        live_idx = np.flatnonzero(~mdp.terminal)
        w[live_idx, actions[live_idx]] = 1.0
        return _policy_matrix(mdp, w)

    b = np.array(r_pi, dtype=np.float64)
    b[mdp.terminal] = 0.0
    info: dict[str, Any] = {}
    if solver == "auto" and actions is not None:
        # Block triangular by the policy graph's strongly connected components: an
        # acyclic graph (self-loops aside) is exact back-substitution in one pass, no
        # matrix, no fill-in (and proper); small cycles add small dense LUs.
        found = component_policy_solve(
            mdp, actions, b, gamma, dense_block_max(mdp.nbytes) if gamma < 1.0 else 1
        )
        if found is not None:
            xt, largest = found
            res = float(np.abs(b - xt + gamma * policy_matvec(mdp, actions, xt)).max(initial=0.0))
            info.update(
                solver=component_solver_name(largest, S),
                residual=res,
                error_bound=res / (1.0 - gamma) if gamma < 1.0 else None,
            )
            return xt, info
    if gamma == 1.0:
        require_terminal_reachable(mdp, matrix(), "the policy")
    use_direct = solver == "direct" or (
        solver == "auto" and int((~mdp.terminal).sum()) <= DIRECT_MAX_STATES
    )
    x: NDArray[np.float64] | None = None
    if (
        solver == "auto"
        and gamma < 1.0
        and actions is not None
        and S <= DENSE_MAX_STATES
        and mdp.nbytes >= 8 * S * S
    ):
        Md = dense_policy_system(mdp, actions, gamma)
        x = np.asarray(np.linalg.solve(Md, b), dtype=np.float64)
        res = float(np.abs(b - Md @ x).max(initial=0.0))
        info.update(solver="direct (dense LU)", residual=res, error_bound=res / (1.0 - gamma))
    if not use_direct and x is None:
        if actions is not None:
            acts = np.ascontiguousarray(actions, dtype=np.int64)

            def mv(y: NDArray[np.float64]) -> NDArray[np.float64]:
                return np.asarray(y - gamma * policy_matvec(mdp, acts, y))
        else:
            P = matrix()

            def mv(y: NDArray[np.float64]) -> NDArray[np.float64]:
                return np.asarray(y - gamma * (P @ y))

        op = spla.LinearOperator((S, S), matvec=mv, dtype=np.float64)
        r_max = float(np.abs(b).max(initial=0.0))
        if gamma < 1.0:
            # ||v - v_pi||_inf <= ||residual||_inf / (1 - gamma)
            target_err = tol if tol is not None else KRYLOV_RTOL * max(1.0, r_max / (1 - gamma))
            target_res = target_err * (1.0 - gamma)
        else:
            # no a-priori bound at gamma = 1: ask for a tiny relative residual instead
            target_res = (tol if tol is not None else KRYLOV_RTOL) * 1e-2 * max(1.0, r_max)
        start = x0
        if solver == "auto" and gamma < 1.0:
            # Sweeps with MacQueen's extrapolation first: on well-mixing chains (random
            # graphs) they reach the target in a few dozen cheap products, with a proof.
            xs, sweeps, bound = _macqueen_sweeps(mv, b, x0, ~mdp.terminal, gamma, target_err)
            if bound is not None:
                x = xs
                res = float(np.abs(b - mv(x)).max(initial=0.0))
                info.update(
                    solver="sweeps (MacQueen bounds)",
                    sweeps=sweeps,
                    residual=res,
                    error_bound=bound,
                )
            start = xs  # slow mixing: hand the sweeps' estimate to GMRES
        n_live = int((~mdp.terminal).sum())
        slow_local = solver == "auto" and n_live <= LU_AFTER_SWEEPS_MAX_STATES
        if x is None and slow_local:
            # The sweeps did not finish (gamma = 1, or a slowly mixing chain): such
            # chains are local (grids, lines, queues), whose sparse LU fills in little,
            # while unpreconditioned GMRES crawls on them. Straight to the LU.
            info["krylov_fallback"] = "slow mixing: sparse LU without GMRES"
        elif x is None:
            xg, its, res = _gmres_refined(op, b, start, target_res)
            if res <= target_res:
                x = xg
                info.update(
                    solver="krylov (GMRES)",
                    krylov_iterations=its,
                    residual=res,
                    error_bound=res / (1.0 - gamma) if gamma < 1.0 else None,
                )
            else:
                info["krylov_fallback"] = f"GMRES stalled at residual {res:.3g}; used sparse LU"
    if x is None:
        M = sp.csc_array(sp.eye_array(S, format="csr") - gamma * matrix())
        x = np.asarray(spla.spsolve(M, b), dtype=np.float64)
        res = float(np.abs(b - M @ x).max(initial=0.0))
        info.update(
            solver="direct (sparse LU)",
            residual=res,
            error_bound=res / (1.0 - gamma) if gamma < 1.0 else None,
        )
    x[mdp.terminal] = 0.0
    return x, info


def _macqueen_sweeps(
    mv: Any,
    b: NDArray[np.float64],
    x0: NDArray[np.float64] | None,
    live: NDArray[np.bool_],
    gamma: float,
    target: float,
    max_sweeps: int = 60,
) -> tuple[NDArray[np.float64], int, float | None]:
    """Sweeps x <- b + gamma P x stopped by MacQueen's bound (see ``span_bounds``).

    ``mv(y) = y - gamma P y``, so b + gamma P x = b + x - mv(x). Returns the estimate,
    the sweeps used and the proven sup-norm error bound, or None for the bound if
    ``max_sweeps`` did not suffice (the chain mixes slowly; GMRES takes over).
    """
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64)
    has_terminal = not bool(live.all())
    for k in range(1, max_sweeps + 1):
        tx = b + x - mv(x)
        tx[~live] = 0.0
        shift, bound = span_bounds((tx - x)[live], gamma, has_terminal)
        if bound <= target:
            tx[live] += shift
            return tx, k, bound
        x = tx
    return x, max_sweeps, None


def _matvec(p: sp.csr_array | None, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """P @ x for a matrix that the caller knows to be present."""
    if p is None:
        raise InvalidArgumentError("internal: a policy matrix was expected")
    return np.asarray(p @ x, dtype=np.float64)


def _gmres_refined(
    M: spla.LinearOperator, b: NDArray[np.float64], x0: NDArray[np.float64] | None, target: float
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
            M, r, rtol=1e-8, atol=0.0, restart=40, maxiter=8, callback=cb, callback_type="pr_norm"
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
    mdp: FiniteMDP | PostDecisionMDP,
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
    mdp: FiniteMDP | PostDecisionMDP,
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
    mdp: FiniteMDP | PostDecisionMDP,
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

    On a :class:`~policylab.mdp.PostDecisionMDP` a deterministic policy is evaluated
    exactly by :func:`policylab.planning.postdecision.evaluate_actions` (``method``,
    ``in_place`` and ``solver`` keep their defaults there).

    Raises:
        InvalidPolicyError: If the policy does not fit the MDP, or if gamma = 1 and
            some states never reach a terminal state under the policy (they are named).
    """
    t0 = time.perf_counter()
    pi = as_policy(mdp, policy)  # type: ignore[arg-type]  # (duck-typed on both models)
    g = check_gamma(mdp, gamma)  # type: ignore[arg-type]
    if isinstance(mdp, PostDecisionMDP):
        return _evaluate_post_decision(mdp, pi, g, method, tol, v0, return_result, t0)
    if method not in ("exact", "iterative"):
        raise InvalidArgumentError(f"method must be 'exact' or 'iterative'; got {method!r}")
    start = np.zeros(mdp.n_states) if v0 is None else check_v(mdp, v0, "v0").copy()
    start[mdp.terminal] = 0.0
    acts = np.asarray(pi.probs.argmax(axis=1), dtype=np.int64) if pi.is_deterministic else None
    p_pi = None if acts is not None else _policy_matrix(mdp, pi.probs)
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
            actions=acts,
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
        graph = p_pi if p_pi is not None else _policy_matrix(mdp, pi.probs)
        require_terminal_reachable(mdp, graph, "the policy")
    probs = np.asarray(pi.probs)

    def sync(v: NDArray[np.float64]) -> NDArray[np.float64]:
        pv = policy_matvec(mdp, acts, v) if acts is not None else _matvec(p_pi, v)
        out = r_pi + g * pv
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


def _evaluate_post_decision(
    mdp: PostDecisionMDP,
    pi: Any,
    gamma: float,
    method: str,
    tol: float | None,
    v0: ArrayLike | None,
    return_result: bool,
    t0: float,
) -> NDArray[np.float64] | PlanningResult:
    """:func:`evaluate_policy` on a PostDecisionMDP (deterministic policies, exact)."""
    from policylab.planning import postdecision

    if method != "exact":
        raise InvalidArgumentError(
            f"method {method!r} applies to a FiniteMDP's outcome table; a PostDecisionMDP's "
            "policies are evaluated exactly (method='exact')"
        )
    if not pi.is_deterministic:
        raise InvalidArgumentError(
            "a PostDecisionMDP evaluates deterministic policies (one action per state); "
            "evaluate a stochastic one on model.to_finite_mdp()"
        )
    acts = np.asarray(pi.probs.argmax(axis=1), dtype=np.int64)
    x0 = None if v0 is None else check_v(mdp, v0, "v0")  # type: ignore[arg-type]
    v, info = postdecision.evaluate_actions(
        mdp,
        acts,
        postdecision._check_gamma(mdp, gamma),
        tol=None if tol is None else check_tol(tol),
        x0=x0,
    )
    if not return_result:
        return v
    return PlanningResult(
        v=v,
        q=postdecision.q_values(mdp, v, gamma),
        policy=pi,
        iterations=1,
        converged=True,
        history=np.asarray([info["residual"]]),
        method="evaluate (exact, post-decision)",
        gamma=gamma,
        residual=info["residual"],
        error_bound=info["error_bound"],
        seconds=time.perf_counter() - t0,
        info=info,
    )
