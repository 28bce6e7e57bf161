"""Linear programming, finite-horizon backward induction and relative value iteration.

These complete the classical solvers that pymdptoolbox offers.
"""

from __future__ import annotations

import time
import warnings
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from policylab.exceptions import InvalidArgumentError, InvalidMDPError, NotConvergedWarning
from policylab.planning._checks import check_gamma, check_positive_int, check_tol, check_v
from policylab.planning.bellman import DEFAULT_TIE_TOL, _q, greedy_policy
from policylab.planning.control import _masked_reward, _require_episodic
from policylab.planning.result import PlanningResult

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = ["backward_induction", "linear_programming", "relative_value_iteration"]


def linear_programming(
    mdp: FiniteMDP, *, gamma: float | None = None, tie_tol: float = DEFAULT_TIE_TOL
) -> PlanningResult:
    """v_* as the solution of the primal linear program (Puterman 6.9), by scipy's HiGHS.

        minimise    sum_{s in S} v(s)
        subject to  v(s) >= r(s, a) + gamma sum_{s' in S} p(s' | s, a) v(s')
                    for every non-terminal s and every a in A(s),

    with v = 0 on terminal states. The smallest v satisfying every constraint is v_*,
    since each constraint says v >= T v. This is an independent check of the other
    solvers; its accuracy is HiGHS's feasibility tolerance (about 1e-7, relative).
    With gamma = 1 the program is bounded only for episodic tasks.

    Returns:
        A :class:`PlanningResult`; ``iterations`` is HiGHS's iteration count and
        ``info["status"]`` its message.

    Raises:
        InvalidMDPError: If the program is infeasible or unbounded (gamma = 1 with a
            cycle of positive reward, for example).
    """
    from scipy.optimize import linprog

    t0 = time.perf_counter()
    g = check_gamma(mdp, gamma)
    if g == 1.0:
        _require_episodic(mdp, "linear programming")
    S, A = mdp.n_states, mdp.n_actions
    live = np.flatnonzero(~mdp.terminal)
    col_of = np.full(S, -1)
    col_of[live] = np.arange(len(live))
    rows = np.flatnonzero(mdp.action_mask.ravel())  # available (s, a), s non-terminal
    tm = sp.csr_array(mdp.transition_matrix[rows][:, live])
    own = sp.csr_array(
        (np.ones(len(rows)), (np.arange(len(rows)), col_of[rows // A])), shape=tm.shape
    )
    # g P v - v <= -r   <=>   v >= r + g P v
    A_ub = sp.csr_array(g * tm - own)
    b_ub = -mdp.expected_reward.ravel()[rows]
    res = linprog(np.ones(len(live)), A_ub=A_ub, b_ub=b_ub, bounds=(None, None), method="highs")
    if res.status != 0 or res.x is None:
        raise InvalidMDPError(
            f"the linear program of MDP {mdp.name!r} has no solution (HiGHS: {res.message}); "
            "with gamma = 1 this means some policy collects unbounded reward"
        )
    v = np.zeros(S)
    v[live] = res.x
    q = _q(mdp, v, g)
    tv = q.max(axis=1)
    tv[mdp.terminal] = 0.0
    residual = float(np.abs(tv - v).max())
    return PlanningResult(
        v=v,
        q=q,
        policy=greedy_policy(mdp, q, tie_tol, proper=g == 1.0),
        iterations=int(res.nit),
        converged=True,
        history=np.asarray([residual]),
        method="linear programming (HiGHS)",
        gamma=g,
        residual=residual,
        error_bound=residual / (1.0 - g) if g < 1.0 else None,
        seconds=time.perf_counter() - t0,
        info={"status": str(res.message)},
    )


def backward_induction(
    mdp: FiniteMDP,
    horizon: int,
    *,
    gamma: float | None = None,
    terminal_values: ArrayLike | None = None,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Finite-horizon dynamic programming (Puterman 4.5): H decisions, then stop.

        v_H(s) = terminal_values(s),
        v_t(s) = max_{a in A(s)} [r(s, a) + gamma sum_{s'} p(s' | s, a) v_{t+1}(s')],
        pi_t(s) = the maximising a,   t = H-1, ..., 0.

    The optimal policy of a finite horizon depends on the time left; ``stage_actions[t]``
    holds pi_t. gamma = 1 is fine (the sums are finite).

    Args:
        mdp: The MDP.
        horizon: H >= 1, the number of decisions.
        gamma: Discount rate; default ``mdp.gamma``.
        terminal_values: v_H (S,), the salvage value; default 0.
        tie_tol: Tie tolerance of the greedy choices (lowest index wins).

    Returns:
        A :class:`PlanningResult` with ``v`` = v_0, ``q`` = q_0, ``policy`` = pi_0,
        ``stage_values`` (H + 1, S) and ``stage_actions`` (H, S) (-1 on terminal states).
    """
    t0 = time.perf_counter()
    g = check_gamma(mdp, gamma)
    H = check_positive_int(horizon, "horizon")
    S, A = mdp.n_states, mdp.n_actions
    vals = np.zeros((H + 1, S))
    if terminal_values is not None:
        vals[H] = check_v(mdp, terminal_values, "terminal_values")
        vals[H, mdp.terminal] = 0.0
    acts = np.full((H, S), -1, dtype=np.int64)
    q = np.zeros((S, A))
    for t in range(H - 1, -1, -1):
        q = _q(mdp, vals[t + 1], g)
        pol = greedy_policy(mdp, q, tie_tol)
        acts[t] = pol.action_indices()
        vals[t] = q.max(axis=1)
        vals[t, mdp.terminal] = 0.0
    return PlanningResult(
        v=vals[0].copy(),
        q=q,
        policy=greedy_policy(mdp, q, tie_tol),
        iterations=H,
        converged=True,
        history=np.zeros(0),
        method=f"backward induction (H={H})",
        gamma=g,
        residual=0.0,
        error_bound=0.0,
        seconds=time.perf_counter() - t0,
        stage_values=vals,
        stage_actions=acts,
    )


#: Relative value iteration reports a multichain MDP when, for this many sweeps in a
#: row, no d(s) = (T h - h)(s) moved by more than this fraction of max d - min d. A
#: unichain MDP whose d narrows that slowly (span shrinking by a factor 1 - 1e-6 per
#: sweep) would need millions of sweeps anyway.
_MULTICHAIN_RATIO = 1e-6
_MULTICHAIN_SWEEPS = 5


def _raise_multichain(mdp: FiniteMDP, d: NDArray[np.float64], sweeps: int) -> None:
    lo, hi = int(d.argmin()), int(d.argmax())
    raise InvalidMDPError(
        f"relative value iteration on MDP {mdp.name!r}: the optimal gain differs by state "
        f"(a multichain MDP): about {d[lo]:.6g} per step from state {mdp.states[lo]!r} but "
        f"{d[hi]:.6g} from state {mdp.states[hi]!r} (steady after {sweeps} sweeps). The "
        "average-reward equation g + h = T h needs one gain for every state (a unichain or "
        "communicating MDP); solve each closed set of states separately, or use "
        "value_iteration or policy_iteration with gamma < 1"
    )


def relative_value_iteration(
    mdp: FiniteMDP,
    *,
    tol: float = 1e-8,
    max_iter: int = 100_000,
    reference: int = 0,
    tau: float = 1.0,
    tie_tol: float = DEFAULT_TIE_TOL,
) -> PlanningResult:
    """Relative value iteration for the average reward per step (Puterman 8.5.5).

    The average-reward optimality equation of a unichain, continuing MDP is

        g + h(s) = max_{a in A(s)} [r(s, a) + sum_{s'} p(s' | s, a) h(s')],

    g the optimal gain (reward per step) and h the bias, fixed by h(reference) = 0.
    Each sweep computes w = T h, d = w - h, and sets h = w - w(reference). The gain
    is bracketed by min_s d(s) <= g <= max_s d(s) (Odoni's bounds); the sweeps stop
    when this bracket is narrower than 2 ``tol`` and return its midpoint, so
    ``|res.gain - g| <= res.error_bound <= tol``.

    A periodic optimal chain makes the plain sweeps oscillate: ``tau`` < 1 applies the
    aperiodicity transform p~ = tau p + (1 - tau) delta_s (same gain and optimal
    policies; h is recovered by scaling). gamma is not used.

    Args:
        mdp: A continuing MDP (no terminal states).
        tol: Accuracy of the gain.
        max_iter: The most sweeps (NotConvergedWarning if reached).
        reference: Index of the state whose relative value is 0.
        tau: Aperiodicity transform, in (0, 1].
        tie_tol: Tie tolerance of the greedy policy.

    Returns:
        A :class:`PlanningResult` with ``v`` = h, ``gain`` = g, and ``q`` = r + P h - g.

    Multichain MDPs, whose optimal gain differs by state (two absorbing states with
    different rewards, say), have no solution of this equation: d = T h - h then
    settles on a different value per state instead of narrowing, which is detected
    (d has stopped moving while max d - min d stays wide) and reported.

    Raises:
        InvalidMDPError: If the MDP has terminal states (the average reward of an
            episodic task is not what this computes), or if the optimal gain differs
            by state (a multichain MDP; the message names two states and their gains).
    """
    t0 = time.perf_counter()
    t = check_tol(tol)
    check_positive_int(max_iter, "max_iter")
    if mdp.terminal.any():
        bad = [mdp.states[i] for i in np.flatnonzero(mdp.terminal)[:5]]
        raise InvalidMDPError(
            f"relative value iteration needs a continuing task; MDP {mdp.name!r} has terminal "
            f"states {bad!r}. Use value_iteration or policy_iteration for episodic tasks"
        )
    if isinstance(reference, bool) or not 0 <= int(reference) < mdp.n_states:
        raise InvalidArgumentError(
            f"reference must be a state index in [0, {mdp.n_states}); got {reference!r}"
        )
    if not 0.0 < float(tau) <= 1.0:
        raise InvalidArgumentError(f"tau must be in (0, 1]; got {tau!r}")
    S, A = mdp.n_states, mdp.n_actions
    tm = mdp.transition_matrix
    rm = _masked_reward(mdp)
    h = np.zeros(S)
    history: list[float] = []
    converged = False
    gain = 0.0
    bound = np.inf
    d_prev = np.full(S, np.nan)
    steady = 0
    for _ in range(max_iter):
        q = np.asarray(tm @ h).reshape(S, A) + rm
        w = tau * q.max(axis=1) + (1.0 - tau) * h
        d = (w - h) / tau
        lo, hi = float(d.min()), float(d.max())
        gain, bound = (lo + hi) / 2.0, (hi - lo) / 2.0
        history.append(hi - lo)
        h = w - w[reference]
        if bound <= t:
            converged = True
            break
        if not np.isfinite(bound):
            break
        # Multichain: d = T h - h tends to the optimal gain of each state, so when d has
        # stopped moving while its span stays wide, the gain differs by state.
        moved = float(np.abs(d - d_prev).max())
        steady = steady + 1 if moved <= _MULTICHAIN_RATIO * (hi - lo) else 0
        if steady >= _MULTICHAIN_SWEEPS:
            _raise_multichain(mdp, d, len(history))
        d_prev = d
    if not converged:
        warnings.warn(
            f"relative value iteration stopped after {len(history)} sweeps (max_iter) with the "
            f"gain bracketed only to +-{bound:.3g} > tol {t:g}; a periodic chain may need tau < 1",
            NotConvergedWarning,
            stacklevel=2,
        )
    h = h * tau
    q = np.asarray(tm @ h).reshape(S, A) + rm - gain
    return PlanningResult(
        v=h,
        q=q,
        policy=greedy_policy(mdp, q, tie_tol),
        iterations=len(history),
        converged=converged,
        history=np.asarray(history),
        method="relative value iteration",
        gamma=1.0,
        residual=history[-1] if history else 0.0,
        error_bound=float(bound),
        seconds=time.perf_counter() - t0,
        gain=float(gain),
    )
