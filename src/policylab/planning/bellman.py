"""The Bellman equations of notes section 5, one function per equation.

Every function works on the MDP's own sparse arrays: ``mdp.transition_matrix`` is the
(S * A, S) CSR matrix p(s' | s, a) with row ``s * A + a`` and ``mdp.expected_reward``
is r(s, a) as an (S, A) array. No dense S x S matrix is ever built. Terminal states
have value 0 and no actions; unavailable actions get q = -inf so that they never win
a maximum.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from policylab.mdp.policy import Policy
from policylab.planning._checks import (
    PolicyLike,
    as_policy,
    check_gamma,
    check_q,
    check_tol,
    check_v,
)

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "DEFAULT_TIE_TOL",
    "action_values",
    "bellman_expectation_backup",
    "bellman_optimality_backup",
    "greedy_actions",
    "greedy_policy",
    "optimal_actions",
    "policy_reward",
    "policy_transition_matrix",
    "proper_actions",
    "state_values",
]

#: Default tolerance for ties between action values: a is optimal in s when
#: q(s, a) >= max_b q(s, b) - DEFAULT_TIE_TOL * max(1, |max_b q(s, b)|).
DEFAULT_TIE_TOL = 1e-9


def action_values(mdp: FiniteMDP, v: ArrayLike, gamma: float | None = None) -> NDArray[np.float64]:
    """Q from v: the one-step lookahead of notes section 5.4.

    q(s, a) = r(s, a) + gamma * sum_{s'} p(s' | s, a) v(s'),
    with r(s, a) = sum_{s', r} p(s', r | s, a) r.

    With v = v_pi this is q_pi; with v = v_* it is q_*.

    Args:
        mdp: The MDP.
        v: State values (S,), in the order of ``mdp.states`` (terminal entries are
            taken as 0, whatever they hold).
        gamma: Discount rate; default ``mdp.gamma``.

    Returns:
        q as an (S, A) array; ``-inf`` where a is not in A(s) (all of a terminal row).
    """
    g = check_gamma(mdp, gamma)
    vv = check_v(mdp, v).copy()
    vv[mdp.terminal] = 0.0
    return _q(mdp, vv, g)


def _q(mdp: FiniteMDP, v: NDArray[np.float64], gamma: float) -> NDArray[np.float64]:
    """Q = r + gamma P v with -inf on unavailable actions (no checks; one compiled pass)."""
    from policylab.planning._kernels import q_values

    q: NDArray[np.float64] = q_values(mdp, gamma, v)
    return q


def _max_q(mdp: FiniteMDP, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """max_a q(s, a) over A(s); 0 for terminal states."""
    v: NDArray[np.float64] = q.max(axis=1)
    v[mdp.terminal] = 0.0
    return v


def bellman_optimality_backup(
    mdp: FiniteMDP, v: ArrayLike, gamma: float | None = None
) -> NDArray[np.float64]:
    """One application of the Bellman optimality operator T.

    (T v)(s) = max_{a in A(s)} sum_{s', r} p(s', r | s, a) [r + gamma v(s')],
    and (T v)(s) = 0 for terminal s. v_* is its fixed point.
    """
    g = check_gamma(mdp, gamma)
    vv = check_v(mdp, v).copy()
    vv[mdp.terminal] = 0.0
    return _max_q(mdp, _q(mdp, vv, g))


def policy_reward(mdp: FiniteMDP, policy: PolicyLike) -> NDArray[np.float64]:
    """r_pi(s) = sum_a pi(a | s) r(s, a), the expected one-step reward under pi (S,)."""
    pi = as_policy(mdp, policy)
    r: NDArray[np.float64] = np.einsum("sa,sa->s", pi.probs, mdp.expected_reward)
    return r


def policy_transition_matrix(mdp: FiniteMDP, policy: PolicyLike) -> sp.csr_array:
    """P_pi(s, s') = sum_a pi(a | s) p(s' | s, a), as a sparse S x S matrix.

    A deterministic policy selects one row of ``mdp.transition_matrix`` per state;
    a stochastic one mixes rows with a sparse (S, S * A) weight matrix.
    """
    pi = as_policy(mdp, policy)
    return _policy_matrix(mdp, pi.probs)


def _policy_matrix(mdp: FiniteMDP, probs: NDArray[np.float64]) -> sp.csr_array:
    S, A = mdp.n_states, mdp.n_actions
    live = ~mdp.terminal
    nnz_per_row = (probs > 0).sum(axis=1)
    if np.all(nnz_per_row[live] == 1):
        # One row of the outcome table per state, copied straight from it (terminal
        # states: none); csr_array sums duplicate next states.
        rows = np.flatnonzero(live) * A + probs.argmax(axis=1)[live]
        starts, ends = mdp.indptr[rows], mdp.indptr[rows + 1]
        lengths = (ends - starts).astype(np.int64)
        indptr = np.zeros(S + 1, dtype=np.int64)
        indptr[1:][live] = lengths
        np.cumsum(indptr, out=indptr)
        take = np.repeat(starts.astype(np.int64) - indptr[:-1][live], lengths)
        take += np.arange(int(indptr[-1]), dtype=np.int64)
        m = sp.csr_array((mdp.probs[take], mdp.next_states[take], indptr), shape=(S, S))
        m.sum_duplicates()
        return m
    tm = mdp.transition_matrix
    s_idx, a_idx = np.nonzero(probs)
    w = sp.csr_array((probs[s_idx, a_idx], (s_idx, s_idx * A + a_idx)), shape=(S, S * A))
    return sp.csr_array(w @ tm)


def bellman_expectation_backup(
    mdp: FiniteMDP, v: ArrayLike, policy: PolicyLike, gamma: float | None = None
) -> NDArray[np.float64]:
    """One application of the Bellman expectation operator T_pi (notes section 5.2.1).

    (T_pi v)(s) = sum_a pi(a | s) sum_{s', r} p(s', r | s, a) [r + gamma v(s')],
    and 0 for terminal s. v_pi is its fixed point.
    """
    g = check_gamma(mdp, gamma)
    pi = as_policy(mdp, policy)
    vv = check_v(mdp, v).copy()
    vv[mdp.terminal] = 0.0
    q = _q(mdp, vv, g)
    return state_values(mdp, np.where(mdp.action_mask, q, 0.0), pi)


def state_values(mdp: FiniteMDP, q: ArrayLike, policy: PolicyLike) -> NDArray[np.float64]:
    """V from q under a policy: v_pi(s) = sum_a pi(a | s) q_pi(s, a) (0 for terminal s)."""
    pi = as_policy(mdp, policy)
    qq = np.where(mdp.action_mask, check_q(mdp, q), 0.0)
    v: NDArray[np.float64] = np.einsum("sa,sa->s", pi.probs, qq)
    v[mdp.terminal] = 0.0
    return v


def optimal_actions(
    mdp: FiniteMDP, q: ArrayLike, tol: float = DEFAULT_TIE_TOL, *, proper: bool = False
) -> NDArray[np.bool_]:
    """The greedy (all maximizing) actions of each state, as a boolean (S, A) mask.

    a is greedy in s when a is in A(s) and
    q(s, a) >= max_{b in A(s)} q(s, b) - tol * max(1, |max_{b in A(s)} q(s, b)|).

    With q = q_* these are all the optimal actions (notes section 5.5); any policy
    that puts its mass on them is optimal. Rows of terminal states are all False.

    ``proper=True`` keeps only the greedy actions that lead toward termination, so
    that every policy on the mask is also *proper* (reaches a terminal state with
    probability 1), which matters at gamma = 1: a zero-reward self-loop can tie with
    the move to the goal, and a policy that takes it never ends the episode. The rule:
    let d(s) be the fewest steps from s to a terminal state along transitions of greedy
    actions (d = 0 on terminal states; a breadth-first search backwards from them, see
    :func:`proper_actions`); in a state with finite d keep the greedy actions that can
    move, with positive probability, to a state with a smaller d. Under any policy on
    these actions every step has a positive probability of lowering d, which is bounded,
    so a terminal state is reached with probability 1, also on stochastic MDPs. With
    q = q_* such a proper optimal policy exists exactly when every state has finite d;
    states with no greedy path to termination keep all their greedy actions (no proper
    optimal choice exists there).
    """
    t = check_tol(tol, "tol") if tol != 0 else 0.0
    qq = np.where(mdp.action_mask, check_q(mdp, q), -np.inf)
    best = qq.max(axis=1, keepdims=True)
    best[mdp.terminal] = 0.0
    mask: NDArray[np.bool_] = mdp.action_mask & (qq >= best - t * np.maximum(1.0, np.abs(best)))
    mask[mdp.terminal] = False
    return proper_actions(mdp, mask) if proper else mask


def proper_actions(mdp: FiniteMDP, allowed: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The actions of ``allowed`` (S, A) that move toward termination (see :func:`optimal_actions`).

    d(s) = 0 on terminal states, d(s) = 1 + min {d(s') : p(s' | s, a) > 0, a allowed in s};
    in a state with finite d the returned mask keeps the allowed actions that can reach
    (p > 0) a state with a smaller d, so every policy on the mask is proper from those
    states; states from which no allowed path reaches a terminal state keep every
    allowed action. With ``allowed = mdp.action_mask`` this yields a proper policy of
    the MDP, with the optimal-action mask a proper optimal one.
    """
    from policylab.planning._kernels import progressing_actions, termination_distances

    allowed = np.asarray(allowed, dtype=bool) & mdp.action_mask
    allowed[mdp.terminal] = False
    dist = termination_distances(mdp, allowed)
    keep = progressing_actions(mdp, allowed, dist)
    stuck = dist < 0
    keep[stuck] = allowed[stuck]
    return keep


def greedy_actions(
    mdp: FiniteMDP, q: ArrayLike, tol: float = DEFAULT_TIE_TOL, *, proper: bool = False
) -> NDArray[np.int64]:
    """The first (lowest-index) greedy action of each state; -1 for terminal states.

    ``proper=True``: the first greedy action that leads toward termination (see
    :func:`optimal_actions`).
    """
    mask = optimal_actions(mdp, q, tol, proper=proper)
    out: NDArray[np.int64] = mask.argmax(axis=1).astype(np.int64)
    out[mdp.terminal] = -1
    return out


def greedy_policy(
    mdp: FiniteMDP,
    q: ArrayLike,
    tol: float = DEFAULT_TIE_TOL,
    ties: str = "first",
    *,
    proper: bool = False,
) -> Policy:
    """The greedy policy pi(s) = argmax_{a in A(s)} q(s, a) (notes section 5.5, q_* -> pi_*).

    Args:
        mdp: The MDP.
        q: Action values (S, A).
        tol: Actions within ``tol * max(1, |max q(s, .)|)`` of the best are tied (see
            :func:`optimal_actions`).
        ties: ``"first"``: a deterministic policy taking the lowest-index tied action
            (in the order of ``mdp.actions``); ``"uniform"``: a stochastic policy
            spreading its mass equally over all tied actions.
        proper: Break ties toward termination: only tied actions that can move to a
            state fewer greedy steps from a terminal state are used (see
            :func:`optimal_actions`), so that with q = q_* at gamma = 1 the policy is
            optimal *and* reaches a terminal state with probability 1 whenever such a
            policy exists. The solvers do this at gamma = 1.

    Returns:
        The greedy :class:`Policy`.
    """
    if ties not in ("first", "uniform"):
        from policylab.exceptions import InvalidArgumentError

        raise InvalidArgumentError(f"ties must be 'first' or 'uniform'; got {ties!r}")
    if ties == "first" and not proper:
        from policylab.planning._kernels import first_greedy_probs

        t = check_tol(tol, "tol") if tol != 0 else 0.0
        return Policy._valid(mdp, first_greedy_probs(mdp, check_q(mdp, q), t))
    mask = optimal_actions(mdp, q, tol, proper=proper)
    if ties == "first":
        acts = mask.argmax(axis=1)
        probs = np.zeros((mdp.n_states, mdp.n_actions))
        live = np.flatnonzero(~mdp.terminal)
        probs[live, acts[live]] = 1.0
    else:
        m = mask.astype(np.float64)
        n = m.sum(axis=1, keepdims=True)
        probs = np.divide(m, n, out=np.zeros_like(m), where=n > 0)
    return Policy(mdp, probs)  # a float64 (S, A) array already: validated, not converted
