"""Applied MDPs: inventory management and pymdptoolbox's forest management.

Both come from the notes' list of applications of MDPs (operations, resources).
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.problems._poisson import poisson_pmf_and_tail
from policylab.problems.registry import register_problem

__all__ = ["forest_management", "inventory_management"]


def inventory_management(
    capacity: int = 10,
    demand_mean: float = 3.0,
    price: float = 8.0,
    unit_cost: float = 4.0,
    order_cost: float = 5.0,
    holding_cost: float = 0.5,
    lost_sale_cost: float = 2.0,
    gamma: float = 0.95,
    *,
    max_order: int | None = None,
    post_decision: bool = False,
) -> Any:
    """A single-product inventory with random demand and lost sales (Puterman 3.2).

    State: the stock at the start of a period, 0..``capacity``. Action: the order
    quantity a in 0..capacity - s (labels are the quantities), delivered at once. The
    period's demand D is Poisson(``demand_mean``); sales are min(s + a, D), unmet
    demand is lost, and the next state is s + a - sales. The reward of a period is

        price * sales - (order_cost * [a > 0] + unit_cost * a)
        - holding_cost * (next stock) - lost_sale_cost * (lost sales).

    Outcomes are exact: every demand below the stock on hand gives its own next
    state; all larger demands leave 0 in stock and share one outcome whose reward uses
    the conditional expectation of the lost sales, E[D - y | D >= y]. A continuing
    task, gamma = 0.95 by default; ``meta`` gives figures the stock axis.

    ``max_order`` caps the order at that many units (a in 0..min(max_order, capacity -
    s)); by default any order that fits is allowed.

    ``post_decision=True`` returns the same MDP as a
    :class:`~policylab.mdp.PostDecisionMDP`: the order takes the stock s surely to the
    stock on hand y = s + a (the post-decision state) with the expected reward
    r(s, a) = -(order_cost [a > 0] + unit_cost a) + price E[min(y, D)] - holding_cost
    E[(y - D)^+] - lost_sale_cost E[(D - y)^+], and the demand takes y to max(y - D, 0)
    by a sparse kernel (entries below the smallest double are zero). Its size grows as
    S * A plus the kernel's where the outcome table's grows as S * A times the
    outcomes of a row, so it reaches 10^5 states (``capacity=99_999`` with a
    ``max_order``).
    """
    if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
        raise InvalidArgumentError(f"capacity must be an integer >= 1; got {capacity!r}")
    if not demand_mean > 0:
        raise InvalidArgumentError(f"demand_mean must be > 0; got {demand_mean!r}")
    if max_order is None:
        max_order = capacity
    if isinstance(max_order, bool) or not isinstance(max_order, int) or max_order < 0:
        raise InvalidArgumentError(f"max_order must be an integer >= 0; got {max_order!r}")
    max_order = min(max_order, capacity)
    if post_decision:
        return _inventory_post_decision(
            capacity,
            demand_mean,
            price,
            unit_cost,
            order_cost,
            holding_cost,
            lost_sale_cost,
            gamma,
            max_order,
        )
    if (capacity + 1) * (max_order + 1) * min(capacity + 1, 400) > 100_000_000:
        raise InvalidArgumentError(
            f"inventory_management(capacity={capacity}) as an outcome table would hold more "
            "than 10^8 outcomes; pass post_decision=True (and a max_order) for the same MDP "
            "in the post-decision form"
        )
    dynamics: dict[Hashable, Any] = {}
    k = np.arange(capacity + 1)
    pmf, tails = poisson_pmf_and_tail(capacity + 1, demand_mean)  # tails[y] = P(D >= y)
    for s in range(capacity + 1):
        acts: dict[int, list[tuple[float, int, float]]] = {}
        for a in range(min(capacity - s, max_order) + 1):
            y = s + a  # stock on hand
            fixed = -(order_cost if a > 0 else 0.0) - unit_cost * a
            outs = []
            for d in range(y):
                nxt = y - d
                outs.append((float(pmf[d]), nxt, fixed + price * d - holding_cost * nxt))
            tail = float(tails[y])  # P(D >= y)
            if tail > 0:
                # E[(D - y)^+] = mean - y + sum_{d < y} (y - d) p(d); divide by P(D >= y)
                excess = demand_mean - y + float(np.sum((y - k[:y]) * pmf[:y]))
                lost = max(excess, 0.0) / tail
                outs.append((tail, 0, fixed + price * y - lost_sale_cost * lost))
            total = sum(p for p, _, _ in outs)
            acts[a] = [(p / total, n, r) for p, n, r in outs]
        dynamics[s] = acts
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=gamma,
        actions=list(range(max_order + 1)),
        initial=0,
        name="inventory-management",
        meta={"x": list(range(capacity + 1)), "xlabel": "Stock"},
    )


def _inventory_post_decision(
    capacity: int,
    demand_mean: float,
    price: float,
    unit_cost: float,
    order_cost: float,
    holding_cost: float,
    lost_sale_cost: float,
    gamma: float,
    max_order: int,
) -> Any:
    """:func:`inventory_management` as a PostDecisionMDP (see its docstring)."""
    import scipy.sparse as sp

    from policylab.mdp.postdecision import PostDecisionMDP

    n = capacity + 1
    d = np.arange(n)
    pmf, tail = poisson_pmf_and_tail(n, demand_mean)  # tail[y] = P(D >= y)
    # E[min(y, D)] = sum_{d < y} d p(d) + y P(D >= y), for y = 0..capacity
    below = np.concatenate([[0.0], np.cumsum(d * pmf)[:-1]])
    sales = below + d * tail
    stock_left = d - sales  # E[(y - D)^+]
    lost = np.maximum(demand_mean - sales, 0.0)  # E[(D - y)^+]
    g = price * sales - holding_cost * stock_left - lost_sale_cost * lost
    # kernel, row y: s' = 0 with P(D >= y), then s' = y - d for the demands d < y, in
    # ascending s' (demands whose probability underflows to 0 are left out)
    nz = int(np.flatnonzero(pmf > 0).max()) + 1
    m = np.minimum(d, nz)  # demands d < y kept in row y
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(1 + m, out=indptr[1:])
    within = _ranges(n, nz)  # 0..m_y - 1 for each row y
    first = np.repeat(indptr[:-1] + 1, m)  # where each row's demand entries start
    cols = np.zeros(int(indptr[-1]), dtype=np.int64)
    vals = np.empty(int(indptr[-1]))
    cols[indptr[:-1]] = 0
    vals[indptr[:-1]] = tail
    ys = np.repeat(d, m)
    lo = ys - np.repeat(m, m) + 1  # the smallest s' = y - (m_y - 1)
    cols[first + within] = lo + within
    vals[first + within] = pmf[np.repeat(m, m) - 1 - within]
    vals /= np.repeat(np.add.reduceat(vals, indptr[:-1]), 1 + m)
    K = sp.csr_array((vals, cols, indptr), shape=(n, n))
    s = d[:, None]
    a = np.arange(max_order + 1)[None, :]
    mask = s + a <= capacity
    post = np.where(mask, s + a, 0)
    reward = np.where(mask, g[post] - unit_cost * a - order_cost * (a > 0), 0.0)
    return PostDecisionMDP(
        post,
        reward,
        K,
        gamma,
        action_mask=mask,
        actions=list(range(max_order + 1)),
        name="inventory-management",
        meta={"xlabel": "Stock"},
    )


def _ranges(n: int, nz: int) -> np.ndarray:
    """The concatenation of arange(min(y, nz)) for y = 0..n-1, without a Python loop."""
    lengths = np.minimum(np.arange(n), nz)
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    out: np.ndarray = np.arange(int(lengths.sum())) - starts
    return out


def forest_management(
    n_states: int = 3, r1: float = 4.0, r2: float = 2.0, p: float = 0.1, gamma: float = 0.9
) -> FiniteMDP:
    """Pymdptoolbox's forest-management problem (``mdptoolbox.example.forest``).

    States 0..S-1 are the age classes of a forest; each year the manager either
    ``wait``s or ``cut``s. A wildfire (probability ``p``) burns the forest back to
    age 0 whatever is done; otherwise waiting ages it by one class (the oldest class
    stays) and cutting resets it to 0. Waiting earns ``r1`` in the oldest class and
    0 elsewhere; cutting earns 0 at age 0, 1 at ages 1..S-2 and ``r2`` in the oldest
    class. As in pymdptoolbox, cutting resets the age with probability 1 (the fire
    does not matter then). gamma = 0.9 as in its policy-iteration example, where
    v_* = (26.244, 29.484, 33.484) and waiting is optimal everywhere.
    """
    if isinstance(n_states, bool) or not isinstance(n_states, int) or n_states < 2:
        raise InvalidArgumentError(f"n_states must be an integer >= 2; got {n_states!r}")
    if not 0.0 <= float(p) <= 1.0:
        raise InvalidArgumentError(f"p must be a probability in [0, 1]; got {p!r}")
    S = n_states
    dynamics: dict[Hashable, Any] = {}
    for s in range(S):
        wait_r = r1 if s == S - 1 else 0.0
        cut_r = r2 if s == S - 1 else (0.0 if s == 0 else 1.0)
        older = min(s + 1, S - 1)
        dynamics[s] = {
            "wait": [(p, 0, wait_r), (1.0 - p, older, wait_r)],
            "cut": [(1.0, 0, cut_r)],
        }
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=gamma,
        actions=["wait", "cut"],
        initial=0,
        name="forest-management",
        meta={"x": list(range(S)), "xlabel": "Forest age class"},
    )


register_problem(
    inventory_management,
    "Inventory: stock 0..10, order 0..10-s, Poisson(3) demand, lost sales, gamma 0.95.",
    max_episode_steps=200,
    section="notes 4 (applications)",
)
register_problem(
    forest_management,
    "pymdptoolbox's forest MDP: wait or cut a forest of 3 age classes, 10% fire risk.",
    max_episode_steps=200,
    section="pymdptoolbox",
)
