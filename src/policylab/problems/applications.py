"""Applied MDPs: inventory management and pymdptoolbox's forest management.

Both come from the notes' list of applications of MDPs (operations, resources).
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import numpy as np
from scipy.stats import poisson

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
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
) -> FiniteMDP:
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
    """
    if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1:
        raise InvalidArgumentError(f"capacity must be an integer >= 1; got {capacity!r}")
    if not demand_mean > 0:
        raise InvalidArgumentError(f"demand_mean must be > 0; got {demand_mean!r}")
    dynamics: dict[Hashable, Any] = {}
    k = np.arange(capacity + 1)
    pmf = poisson.pmf(k, demand_mean)
    for s in range(capacity + 1):
        acts: dict[int, list[tuple[float, int, float]]] = {}
        for a in range(capacity - s + 1):
            y = s + a  # stock on hand
            fixed = -(order_cost if a > 0 else 0.0) - unit_cost * a
            outs = []
            for d in range(y):
                nxt = y - d
                outs.append((float(pmf[d]), nxt, fixed + price * d - holding_cost * nxt))
            tail = float(poisson.sf(y - 1, demand_mean))  # P(D >= y)
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
        actions=list(range(capacity + 1)),
        initial=0,
        name="inventory-management",
        meta={"x": list(range(capacity + 1)), "xlabel": "Stock"},
    )


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
