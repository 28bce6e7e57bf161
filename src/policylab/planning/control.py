"""Optimal control by dynamic programming: value, policy and modified policy iteration.

See Sutton & Barto chapter 4 and Puterman chapter 6.

All three find v_* and an optimal policy pi_* from the Bellman optimality equation

    v_*(s) = max_{a in A(s)} sum_{s', r} p(s', r | s, a) [r + gamma v_*(s')],

working on the model's sparse (S * A, S) transition matrix; unavailable actions get
-inf in every maximum.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from policylab.exceptions import InvalidArgumentError, InvalidMDPError, NotConvergedWarning
from policylab.mdp.policy import Policy
from policylab.mdp.postdecision import PostDecisionMDP
from policylab.planning._checks import (
    PolicyLike,
    as_policy,
    check_gamma,
    check_positive_int,
    check_tol,
    check_v,
    raise_if_stuck,
    require_terminal_reachable,
)
from policylab.planning._kernels import (
    BLOCK_MIN_OUTCOMES,
    gauss_seidel_optimality_sweep,
    improved_actions,
    optimality_sweep,
    optimality_values,
    policy_matvec,
    sweep_blocks,
    termination_distances,
)
from policylab.planning._sweeps import run_sweeps, span_bounds
from policylab.planning.bellman import (
    DEFAULT_TIE_TOL,
    _policy_matrix,
    _q,
    greedy_policy,
    proper_actions,
)
from policylab.planning.evaluation import _matvec, solve_policy_system
from policylab.planning.result import PlanningResult

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "ADAPTIVE_ETA",
    "ADAPTIVE_MAX_M",
    "ADAPTIVE_STALL",
    "modified_policy_iteration",
    "policy_iteration",
    "proper_policy",
    "value_iteration",
]


def _masked_reward(mdp: FiniteMDP) -> NDArray[np.float64]:
    """r(s, a) with -inf on unavailable actions, so that they never win a maximum."""
    return np.where(mdp.action_mask, mdp.expected_reward, -np.inf)


def _all_reach_terminal(mdp: FiniteMDP) -> bool:
    """Whether every state can reach a terminal state under some policy."""
    return bool((termination_distances(mdp, mdp.action_mask) >= 0).all())


def _require_episodic(mdp: FiniteMDP, what: str) -> None:
    """Gamma = 1: every state must be able to reach a terminal state under some policy."""
    stuck = np.flatnonzero(termination_distances(mdp, mdp.action_mask) < 0)
    raise_if_stuck(mdp, stuck, f"{what} (under any policy)", InvalidMDPError)


def _no_postdecision_option(**defaults: bool) -> None:
    """Refuse tabular-only options (each given as "is it at its default?") on a PostDecisionMDP."""
    given = [name for name, ok in defaults.items() if not ok]
    if given:
        raise InvalidArgumentError(
            f"{', '.join(given)} applies to a FiniteMDP's outcome table only, not to a "
            "PostDecisionMDP; leave it at its default (or solve model.to_finite_mdp())"
        )


def value_iteration(
    mdp: FiniteMDP | PostDecisionMDP,
    *,
    tol: float = 1e-8,
    gamma: float | None = None,
    max_iter: int = 100_000,
    gauss_seidel: bool = False,
    order: str | ArrayLike = "auto",
    v0: ArrayLike | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Value iteration: v_{k+1} = T v_k until v_* is known to within ``tol``.

    (T v)(s) = max_{a in A(s)} [r(s, a) + gamma sum_{s'} p(s' | s, a) v(s')].

    Stopping rule (gamma < 1): synchronous sweeps stop as soon as MacQueen's bounds
    v_{k+1} + gamma/(1-gamma) min_s d(s) <= v_* <= v_{k+1} + gamma/(1-gamma) max_s d(s),
    d = v_{k+1} - v_k, pin v_* down to within ``tol``; the midpoint is returned, so
    ``max_s |res.v(s) - v_*(s)| <= res.error_bound <= tol`` is guaranteed, not hoped
    for. This stops far earlier than the textbook rule ||d|| < tol (1-gamma)/(2 gamma)
    when the values move together. Gauss-Seidel sweeps (``gauss_seidel=True``) update
    states in place, one after the other in ``order``, and stop when gamma/(1-gamma)
    max_s |d(s)| <= tol (the in-place sweep is a gamma-contraction too, in any order).
    Each in-place update solves the state's own self-loop exactly (see
    :func:`gauss_seidel_optimality_sweep`), so that slipping in place costs no sweeps.

    Sweep order (Gauss-Seidel only): ``"terminal-first"`` visits the states by their
    distance to the nearest terminal state (fewest steps under any action; states that
    cannot reach one last), so that values flow from the end of the episode backwards
    in one sweep; ``"index"`` is the order of ``mdp.states``; an array gives the order
    itself (a permutation of the state indices); ``"auto"`` is ``"terminal-first"``
    when the MDP has terminal states and ``"index"`` otherwise. Without ``v0`` and
    with gamma < 1, in-place sweeps start from the lower bound min(0, min r) / (1 -
    gamma) <= v_*: from below, an ordered sweep propagates the exact values instead
    of optimistic guesses from states not yet visited.

    gamma = 1 (episodic tasks): every state must be able to reach a terminal state,
    and sweeps stop when max_s |d(s)| <= tol; no sup-norm bound exists in general, so
    ``error_bound`` is None (use :func:`policy_iteration` for an exact answer).

    Args:
        mdp: The MDP.
        tol: Accuracy asked of v (see above).
        gamma: Discount rate; default ``mdp.gamma``.
        max_iter: The most sweeps; a NotConvergedWarning is issued if they run out.
        gauss_seidel: In-place (Gauss-Seidel) sweeps instead of synchronous ones.
        order: Order of the in-place sweeps (see above).
        v0: Starting values (default zeros; see above for in-place sweeps).
        tie_tol: Tie tolerance of the greedy policy (see :func:`greedy_policy`).

    Returns:
        A :class:`PlanningResult`; ``history`` holds max_s |d(s)| of each sweep.

    A :class:`~policylab.mdp.PostDecisionMDP` is solved by synchronous sweeps through its
    post-decision values (see :mod:`policylab.planning.postdecision`), with the same
    stopping rule and bound.
    """
    if isinstance(mdp, PostDecisionMDP):
        _no_postdecision_option(
            gauss_seidel=not gauss_seidel, order=isinstance(order, str) and order == "auto"
        )
        from policylab.planning import postdecision

        return postdecision.value_iteration(
            mdp, tol=tol, gamma=gamma, max_iter=max_iter, v0=v0, tie_tol=tie_tol
        )
    t0 = time.perf_counter()
    g = check_gamma(mdp, gamma)
    t = check_tol(tol)
    check_positive_int(max_iter, "max_iter")
    if g == 1.0:
        _require_episodic(mdp, "value iteration")
    if not gauss_seidel and not (isinstance(order, str) and order == "auto"):
        raise InvalidArgumentError(
            "order applies to in-place sweeps only; pass gauss_seidel=True with it"
        )
    sweep_order, dist = _sweep_order(mdp, order) if gauss_seidel else (None, None)
    blocks = (
        sweep_blocks(mdp, sweep_order, dist)
        if sweep_order is not None and dist is not None and mdp.n_outcomes >= BLOCK_MIN_OUTCOMES
        else None
    )
    if v0 is not None:
        start = check_v(mdp, v0, "v0").copy()
    elif gauss_seidel and g < 1.0:
        r_min = float(_masked_reward(mdp)[mdp.action_mask].min(initial=0.0))
        start = np.full(mdp.n_states, min(0.0, r_min) / (1.0 - g))
    else:
        start = np.zeros(mdp.n_states)
    start[mdp.terminal] = 0.0
    term = mdp.terminal

    def sync(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return optimality_values(mdp, g, v)

    def gs(v: NDArray[np.float64]) -> float:
        return gauss_seidel_optimality_sweep(mdp, g, v, sweep_order, blocks)

    out = run_sweeps(
        synchronous=None if gauss_seidel else sync,
        in_place=gs if gauss_seidel else None,
        v0=start,
        live=~term,
        gamma=g,
        tol=t,
        max_iter=max_iter,
        what="value iteration" + (" (Gauss-Seidel)" if gauss_seidel else ""),
    )
    q = _q(mdp, out.v, g)
    return PlanningResult(
        v=out.v,
        q=q,
        policy=greedy_policy(mdp, q, tie_tol, proper=g == 1.0),
        iterations=out.iterations,
        converged=out.converged,
        history=out.history,
        method="value iteration" + (" (Gauss-Seidel)" if gauss_seidel else ""),
        gamma=g,
        residual=out.residual,
        error_bound=out.error_bound,
        seconds=time.perf_counter() - t0,
    )


def _sweep_order(
    mdp: FiniteMDP, order: str | ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.int64] | None]:
    """The state order of in-place sweeps (see :func:`value_iteration`).

    Returns:
        ``(order, key)``: the permutation, and for the terminal-first order each state's
        distance to a terminal state by which it was sorted (None for the others).
    """
    S = mdp.n_states
    if isinstance(order, str):
        if order not in ("auto", "terminal-first", "index"):
            raise InvalidArgumentError(
                f"order must be 'auto', 'terminal-first', 'index' or a permutation of the "
                f"{S} state indices; got {order!r}"
            )
        if order == "index" or (order == "auto" and not mdp.terminal.any()):
            return np.arange(S, dtype=np.int64), None
        dist = termination_distances(mdp, mdp.action_mask)
        key = np.where(dist < 0, np.iinfo(np.int64).max, dist)
        return np.argsort(key, kind="stable").astype(np.int64), key
    arr = np.asarray(order)
    if (
        arr.shape != (S,)
        or not np.issubdtype(arr.dtype, np.integer)
        or not np.array_equal(np.sort(arr), np.arange(S))
    ):
        raise InvalidArgumentError(
            f"order must be a permutation of the {S} state indices 0..{S - 1}; got an array "
            f"of shape {arr.shape} and dtype {arr.dtype}"
        )
    return arr.astype(np.int64), None


def _one_hot(mdp: FiniteMDP, actions: NDArray[np.int64]) -> NDArray[np.float64]:
    w = np.zeros((mdp.n_states, mdp.n_actions))
    live = np.flatnonzero(~mdp.terminal)
    w[live, actions[live]] = 1.0
    return w


def proper_policy(mdp: FiniteMDP) -> Policy:
    """A deterministic policy that reaches a terminal state with probability 1 from every state.

    Each state takes its first action that can move it, with positive probability, to a
    state fewer steps from a terminal state (the distances of a breadth-first search
    backwards from the terminal states; see :func:`proper_actions`). Every step then has
    a positive probability of getting closer, so termination is certain. Policy
    iteration starts from it when gamma = 1.

    Raises:
        InvalidMDPError: Naming the states from which no policy reaches a terminal state.
    """
    _require_episodic(mdp, "an episodic task")
    acts = proper_actions(mdp, mdp.action_mask).argmax(axis=1)
    return Policy._valid(mdp, _one_hot(mdp, acts))  # each row an available action


def policy_iteration(
    mdp: FiniteMDP | PostDecisionMDP,
    *,
    gamma: float | None = None,
    evaluation: str = "exact",
    policy: PolicyLike | None = None,
    max_iter: int = 1000,
    tol: float | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
    solver: str = "auto",
) -> PlanningResult:
    """Policy iteration: evaluate pi_k, improve it greedily, until the policy is stable.

    Evaluation: v_k = v_{pi_k} solves v = r_pi + gamma P_pi v (exactly, or by sweeps).
    Improvement: pi_{k+1}(s) = argmax_{a in A(s)} [r(s, a) + gamma sum_{s'} p(s'|s, a) v_k(s')],
    keeping pi_k(s) whenever it is within ``tie_tol`` of the best, so the policy never
    cycles between equally good actions. It stops when no state changes its action; the
    returned policy is then greedy with respect to its own values, hence optimal.

    Args:
        mdp: The MDP.
        gamma: Discount rate; default ``mdp.gamma``.
        evaluation: ``"exact"`` (sparse linear solve, see :func:`evaluate_policy`) or
            ``"iterative"`` (synchronous sweeps to ``tol``, warm-started).
        policy: The starting policy (default: :func:`proper_policy` on episodic tasks,
            where every state can reach a terminal state, whatever gamma; otherwise
            greedy in the one-step reward r(s, a)). A stochastic start is evaluated once
            and improved. Heading for the end of the episode is a far better start than
            the one-step reward on problems with long episodes (a chain of n states
            needs n improvements from "all left", one from the proper policy).
        max_iter: The most improvement steps (NotConvergedWarning if reached).
        tol: Evaluation accuracy (iterative sweeps, or GMRES on large systems).
        tie_tol: Tie tolerance of the improvement step.
        solver: Linear solver of exact evaluation: ``"auto"``, ``"direct"``, ``"krylov"``.

    Returns:
        A :class:`PlanningResult`: ``iterations`` counts evaluations; ``history`` the
        number of states whose action changed at each improvement (its last entry is 0
        when converged), so the number of improvements that changed the policy is
        ``(res.history > 0).sum()``.

    A :class:`~policylab.mdp.PostDecisionMDP` is solved by
    :func:`policylab.planning.postdecision.policy_iteration` (exact evaluation, starting
    greedy in r(s, a)).
    """
    if isinstance(mdp, PostDecisionMDP):
        _no_postdecision_option(
            evaluation=evaluation == "exact", policy=policy is None, solver=solver == "auto"
        )
        from policylab.planning import postdecision

        return postdecision.policy_iteration(
            mdp, gamma=gamma, max_iter=max_iter, tol=tol, tie_tol=tie_tol
        )
    t0 = time.perf_counter()
    g = check_gamma(mdp, gamma)
    check_positive_int(max_iter, "max_iter")
    if evaluation not in ("exact", "iterative"):
        raise InvalidArgumentError(f"evaluation must be 'exact' or 'iterative'; got {evaluation!r}")
    S = mdp.n_states
    live = ~mdp.terminal
    R = mdp.expected_reward
    if policy is not None:
        probs = np.asarray(as_policy(mdp, policy).probs)
    elif g == 1.0 or (mdp.terminal.any() and _all_reach_terminal(mdp)):
        probs = np.asarray(proper_policy(mdp).probs)
    else:
        probs = np.asarray(greedy_policy(mdp, mdp.expected_reward).probs)
    current = probs.argmax(axis=1)
    rows = np.arange(S)
    stochastic_start = first_stochastic = bool(np.any((probs > 0).sum(axis=1)[live] > 1))
    eval_tol = None if tol is None else check_tol(tol)
    v = np.zeros(S)
    history: list[float] = []
    converged = False
    info: dict[str, Any] = {}
    bound: float | None = 0.0
    residual = 0.0
    for _ in range(max_iter):
        acts: NDArray[np.int64] | None
        if stochastic_start:
            stochastic_start = False
            acts, p_pi = None, _policy_matrix(mdp, probs)
            r_pi = np.einsum("sa,sa->s", probs, R)
        else:
            acts, p_pi = current.copy(), None
            r_pi = R[rows, current]
            r_pi[mdp.terminal] = 0.0
        if evaluation == "exact":
            v, info = solve_policy_system(
                mdp,
                p_pi,
                r_pi,
                g,
                solver=solver,
                tol=eval_tol,
                x0=v if history else None,
                actions=acts,
            )
            residual = float(info["residual"])
            bound = info["error_bound"]
        else:
            if g == 1.0:
                graph = p_pi if p_pi is not None else _policy_matrix(mdp, _one_hot(mdp, current))
                require_terminal_reachable(mdp, graph, "a policy met by policy iteration")

            def sync(
                x: NDArray[np.float64],
                p_pi: sp.csr_array | None = p_pi,
                acts: NDArray[np.int64] | None = acts,
                r_pi: NDArray[np.float64] = r_pi,
            ) -> NDArray[np.float64]:
                px = policy_matvec(mdp, acts, x) if acts is not None else _matvec(p_pi, x)
                return np.asarray(r_pi + g * px)

            with warnings.catch_warnings():
                warnings.simplefilter("error", NotConvergedWarning)
                out = run_sweeps(
                    synchronous=sync,
                    in_place=None,
                    v0=v,
                    live=live,
                    gamma=g,
                    tol=1e-10 if eval_tol is None else eval_tol,
                    max_iter=100_000,
                    what="policy evaluation",
                )
            v, residual, bound = out.v, out.residual, out.error_bound
        q = _q(mdp, v, g)
        new, changed = improved_actions(mdp, q, current, tie_tol)
        if not history and first_stochastic:
            changed = max(changed, 1)  # a stochastic start always changes to deterministic
        history.append(changed)
        current = new
        if changed == 0:
            converged = True
            break
    if not converged:
        warnings.warn(
            f"policy iteration stopped after {len(history)} improvements (max_iter) with "
            f"{history[-1]:g} states still changing",
            NotConvergedWarning,
            stacklevel=2,
        )
    # current holds each state's argmax of q (-inf off A(s)) or its earlier choice
    pol = Policy._valid(mdp, _one_hot(mdp, current))
    return PlanningResult(
        v=v,
        q=q,
        policy=pol,
        iterations=len(history),
        converged=converged,
        history=np.asarray(history, dtype=np.float64),
        method=f"policy iteration ({evaluation})",
        gamma=g,
        residual=residual,
        error_bound=bound,
        seconds=time.perf_counter() - t0,
        info=dict(info),
    )


#: ``m="adaptive"``: evaluation sweeps stop once the span of their change is below this
#: fraction of the span of the improvement's Bellman residual.
ADAPTIVE_ETA = 0.1
#: ``m="adaptive"``: evaluation sweeps also stop when a sweep shrinks the span of the
#: change by less than this factor (the evaluation has stalled).
ADAPTIVE_STALL = 0.995
#: ``m="adaptive"``: the most evaluation sweeps after one improvement.
ADAPTIVE_MAX_M = 1000


def modified_policy_iteration(
    mdp: FiniteMDP | PostDecisionMDP,
    *,
    m: int | str = 10,
    tol: float = 1e-8,
    gamma: float | None = None,
    max_iter: int = 100_000,
    v0: ArrayLike | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Modified policy iteration (Puterman 6.5): greedy step, then m partial evaluation sweeps.

    Each iteration k computes q_k = r + gamma P v_k, the greedy policy pi_k and
    T v_k = max_a q_k, then v_{k+1} = T_{pi_k}^m (T v_k) by m cheap sweeps with P_pi_k
    (one action per state). m = 0 is value iteration; m -> infinity is policy
    iteration. The stopping rule is value iteration's: MacQueen's bounds on
    d = T v_k - v_k prove max_s |v(s) - v_*(s)| <= ``tol`` (gamma < 1); with gamma = 1
    it stops when max_s |d(s)| <= tol and gives no bound.

    Adaptive m (``m="adaptive"``): after improvement k the evaluation sweeps
    x_{j+1} = T_{pi_k} x_j go on while they are worth their cost, judged by the span
    sp(x) = max_s x(s) - min_s x(s) of their change Delta_j = x_{j+1} - x_j (the span is
    what MacQueen's bounds, hence the stopping rule, measure). They stop at the first j
    where sp(Delta_j) <= eta sp(d_k) (the policy's values are then known far better
    than the improvement step can use; eta = :data:`ADAPTIVE_ETA`), or where
    sp(Delta_j) > rho sp(Delta_{j-1}) (the span no longer shrinks: the evaluation has
    stalled; rho = :data:`ADAPTIVE_STALL`), or after :data:`ADAPTIVE_MAX_M` sweeps. So
    m grows where policies mix slowly and their evaluation keeps paying, and shrinks to
    a few sweeps where the values settle at once. Any sequence m_k keeps the stopping
    rule's proof: the bound is computed from d = T v_k - v_k whatever v_k is.

    Args:
        mdp: The MDP.
        m: Partial evaluation sweeps per improvement, or ``"adaptive"`` (see above).
        tol: Accuracy asked of v.
        gamma: Discount rate; default ``mdp.gamma``.
        max_iter: The most improvements (NotConvergedWarning if reached).
        v0: Starting values (default zeros).
        tie_tol: Tie tolerance of the greedy policy.

    Returns:
        A :class:`PlanningResult`; ``history`` holds max_s |T v_k(s) - v_k(s)|.

    A :class:`~policylab.mdp.PostDecisionMDP` is solved by the same rules through its
    post-decision values (:mod:`policylab.planning.postdecision`).
    """
    if isinstance(mdp, PostDecisionMDP):
        from policylab.planning import postdecision

        return postdecision.modified_policy_iteration(
            mdp, m=m, tol=tol, gamma=gamma, max_iter=max_iter, v0=v0, tie_tol=tie_tol
        )
    t0 = time.perf_counter()
    g = check_gamma(mdp, gamma)
    t, m_sweeps = mpi_arguments(tol, max_iter, m)
    if g == 1.0:
        _require_episodic(mdp, "modified policy iteration")
    S = mdp.n_states
    live = ~mdp.terminal
    R = mdp.expected_reward
    v = np.zeros(S) if v0 is None else check_v(mdp, v0, "v0").copy()
    v[mdp.terminal] = 0.0
    rows = np.arange(S)
    work = np.empty((S, mdp.n_actions))  # q, reused by every sweep

    def optimality(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        return optimality_sweep(mdp, g, x, work)

    def policy_backup(
        act: NDArray[np.int64],
    ) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
        r_pi = R[rows, np.maximum(act, 0)]
        r_pi[mdp.terminal] = 0.0
        return lambda x: r_pi + g * policy_matvec(mdp, act, x)

    v, history, sweeps, converged, bound, residual = mpi_iterations(
        optimality, policy_backup, v, live, g, t, max_iter, m_sweeps
    )
    if not converged:
        warnings.warn(
            f"modified policy iteration stopped after {len(history)} improvements (max_iter): "
            f"last change {residual:.3g} > tol {t:g}",
            NotConvergedWarning,
            stacklevel=2,
        )
    q = _q(mdp, v, g)
    return PlanningResult(
        v=v,
        q=q,
        policy=greedy_policy(mdp, q, tie_tol, proper=g == 1.0),
        iterations=len(history),
        converged=converged,
        history=np.asarray(history),
        method=f"modified policy iteration (m={m})",
        gamma=g,
        residual=residual,
        error_bound=bound if g < 1.0 else None,
        seconds=time.perf_counter() - t0,
        info={"evaluation_sweeps": sweeps} if m_sweeps is None else {},
    )


def mpi_arguments(tol: float, max_iter: int, m: int | str) -> tuple[float, int | None]:
    """Checked ``tol`` and ``max_iter`` of modified policy iteration, and m (None: adaptive)."""
    t = check_tol(tol)
    check_positive_int(max_iter, "max_iter")
    if isinstance(m, str):
        if m != "adaptive":
            raise InvalidArgumentError(f"m must be an integer >= 0 or 'adaptive'; got {m!r}")
        return t, None
    return t, check_positive_int(m, "m", minimum=0)


def _span(x: NDArray[np.float64]) -> float:
    """sp(x) = max_s x(s) - min_s x(s) (0 for an empty x)."""
    return float(x.max() - x.min()) if x.size else 0.0


def mpi_iterations(
    optimality: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.int64]]],
    policy_backup: Callable[
        [NDArray[np.int64]], Callable[[NDArray[np.float64]], NDArray[np.float64]]
    ],
    v: NDArray[np.float64],
    live: NDArray[np.bool_],
    gamma: float,
    tol: float,
    max_iter: int,
    m: int | None,
) -> tuple[NDArray[np.float64], list[float], list[int], bool, float | None, float]:
    """The loop of :func:`modified_policy_iteration`, for any model's two backups.

    Args:
        optimality: v -> (T v, a greedy action per state).
        policy_backup: actions -> the policy's backup x -> r_pi + gamma P_pi x.
        v: Starting values.
        live: Non-terminal states.
        gamma: Discount rate.
        tol: Accuracy asked of v (MacQueen's bounds on d = T v_k - v_k, gamma < 1).
        max_iter: The most improvements.
        m: Evaluation sweeps per improvement; None for the adaptive rule.

    Returns:
        ``(v, history of max|d|, evaluation sweeps of each improvement (adaptive),
        converged, error bound, last max|d|)``.
    """
    has_terminal = not bool(live.all())
    history: list[float] = []
    sweeps: list[int] = []
    converged = False
    bound: float | None = None
    residual = np.inf
    for _ in range(max_iter):
        tv, act = optimality(v)
        d = tv - v
        residual = float(np.abs(d).max())
        history.append(residual)
        if gamma < 1.0:
            shift, bound = span_bounds(d[live], gamma, has_terminal)
            if bound <= tol:
                tv[live] += shift
                v = tv
                converged = True
                break
        elif residual <= tol:
            v = tv
            converged = True
            break
        if not np.isfinite(residual):
            v = tv
            break
        v = tv
        if m is None:
            v, n_eval = _adaptive_evaluation(policy_backup(act), v, _span(d[live]), live)
            sweeps.append(n_eval)
        elif m:
            backup = policy_backup(act)
            for _k in range(m):
                v = backup(v)
    return v, history, sweeps, converged, bound if gamma < 1.0 else None, residual


def _adaptive_evaluation(
    backup: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    v: NDArray[np.float64],
    residual_span: float,
    live: NDArray[np.bool_],
) -> tuple[NDArray[np.float64], int]:
    """Sweeps v <- backup(v) = r_pi + gamma P_pi v by :func:`modified_policy_iteration`'s rule.

    Returns the values and the number of sweeps made.
    """
    target = ADAPTIVE_ETA * residual_span
    last = np.inf
    for j in range(1, ADAPTIVE_MAX_M + 1):
        new = backup(v)
        change = _span((new - v)[live])
        v = new
        if change <= target or change > ADAPTIVE_STALL * last:
            return v, j
        last = change
    return v, ADAPTIVE_MAX_M
