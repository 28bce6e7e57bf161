"""The temporal-difference update rules, one function per equation (Sutton & Barto).

Each is a small numba-compilable function (``register_jitable``: inlined into the
compiled episode loops, and plain Python when a loop runs as Python over a Gymnasium
env). A target never bootstraps past a terminated step: V(terminal) = 0.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba.extending import register_jitable

from policylab.tabular.kernels import epsilon_greedy_prob

__all__ = [
    "double_q_target",
    "expected_sarsa_target",
    "n_step_return",
    "q_learning_target",
    "sarsa_target",
    "td_error",
    "td_target",
    "td_update",
]


@register_jitable
def td_update(estimate: float, alpha: float, target: float) -> float:
    """NewEstimate = OldEstimate + alpha [Target - OldEstimate]  (S&B eq. 2.4, section 2.4)."""
    return estimate + alpha * (target - estimate)


@register_jitable
def td_target(r: float, gamma: float, v_next: float, terminated: bool) -> float:
    """The TD(0) target R_{t+1} + gamma V(S_{t+1}), V(terminal) = 0  (S&B eq. 6.2, section 6.1)."""
    if terminated:
        return r
    return r + gamma * v_next


@register_jitable
def td_error(r: float, gamma: float, v_next: float, v: float, terminated: bool) -> float:
    """The TD error delta_t = R_{t+1} + gamma V(S_{t+1}) - V(S_t)  (S&B eq. 6.5, section 6.1)."""
    return td_target(r, gamma, v_next, terminated) - v


@register_jitable
def sarsa_target(r: float, gamma: float, q_next: float, terminated: bool) -> float:
    """The Sarsa target R_{t+1} + gamma Q(S_{t+1}, A_{t+1})  (S&B eq. 6.7, section 6.4)."""
    if terminated:
        return r
    return r + gamma * q_next


@register_jitable
def q_learning_target(
    r: float, gamma: float, q: Any, mask: Any, s_next: int, terminated: bool
) -> float:
    """The Q-learning target R_{t+1} + gamma max_a Q(S_{t+1}, a)  (S&B eq. 6.8, section 6.5).

    ``q`` and ``mask`` are the whole (S, A) tables and ``s_next`` the row of S_{t+1}
    (indexing them here, rather than passing a row view, keeps the compiled step loop
    free of array temporaries). The max ranges over A(S_{t+1}) only.
    """
    if terminated:
        return r
    best = -np.inf
    for a in range(q.shape[1]):
        if mask[s_next, a] and q[s_next, a] > best:
            best = q[s_next, a]
    return r + gamma * best


@register_jitable
def expected_sarsa_target(
    r: float, gamma: float, q_next_row: Any, mask_row: Any, epsilon: float, terminated: bool
) -> float:
    """R_{t+1} + gamma sum_a pi(a | S_{t+1}) Q(S_{t+1}, a)  (S&B eq. 6.9, section 6.6).

    pi is the behaviour policy's epsilon-greedy (ties shared), as
    :func:`~policylab.tabular.kernels.epsilon_greedy_prob` gives it.
    """
    if terminated:
        return r
    expected = 0.0
    for a in range(q_next_row.shape[0]):
        if mask_row[a]:
            expected += epsilon_greedy_prob(q_next_row, mask_row, epsilon, a) * q_next_row[a]
    return r + gamma * expected


@register_jitable
def double_q_target(
    r: float, gamma: float, q_select_row: Any, q_eval_row: Any, mask_row: Any, terminated: bool
) -> float:
    """R_{t+1} + gamma Q2(S_{t+1}, argmax_a Q1(S_{t+1}, a))  (S&B eq. 6.10, section 6.7).

    One table picks the action (its first maximiser), the other values it.
    """
    if terminated:
        return r
    best = -np.inf
    arg = 0
    for a in range(q_select_row.shape[0]):
        if mask_row[a] and q_select_row[a] > best:
            best = q_select_row[a]
            arg = a
    return r + gamma * float(q_eval_row[arg])


@register_jitable
def n_step_return(rewards: Any, start: int, end: int, gamma: float) -> tuple[float, float]:
    """The n-step return's rewards sum_{i=start+1}^{end} gamma^{i-start-1} R_i  (S&B eq. 7.1).

    Also returns gamma^{end-start}, the discount of the bootstrap term (section 7.1).
    ``rewards`` is a ring buffer indexed ``i % len(rewards)``.
    """
    m = rewards.shape[0]
    g = 0.0
    p = 1.0
    for i in range(start + 1, end + 1):
        g += p * rewards[i % m]
        p *= gamma
    return g, p
