"""Every method, ``auto`` included, reaches the same optimum on each benchmark family.

Small instances of the families of ``benchmarks/bench_planning.py``; the oracle is
policy iteration with a sparse LU (exact to rounding), cross-checked against closed
forms where the family has one and against linear programming.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.planning import METHODS, choose_method, linear_programming, solve
from policylab.problems import inventory_management, jacks_car_rental, random_mdp
from policylab.problems.generators import long_chain, slip_gridworld

TOL = 1e-8

FAMILIES = {
    "random": lambda: random_mdp(300, 4, 5, seed=3, gamma=0.95),
    "grid-0.99": lambda: slip_gridworld(12, 0.1, gamma=0.99),
    "grid-0.999": lambda: slip_gridworld(12, 0.2, gamma=0.999),
    "grid-shortest-path": lambda: slip_gridworld(12, 0.1, gamma=1.0),
    "chain-0.999": lambda: long_chain(150, 0.8, gamma=0.999),
    "chain-shortest-path": lambda: long_chain(150, 0.8, gamma=1.0),
    "inventory": lambda: inventory_management(capacity=15),
    "inventory-max-order": lambda: inventory_management(capacity=40, max_order=8),
    "jacks-car-rental": lambda: jacks_car_rental(max_cars=6, max_move=2),
}


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_method_reaches_the_optimum(family: str) -> None:
    mdp = FAMILIES[family]()
    ref = pl.policy_iteration(mdp, solver="direct")
    scale = max(1.0, float(np.abs(ref.v).max()))
    lp = linear_programming(mdp)
    assert np.allclose(lp.v, ref.v, atol=1e-6 * scale)
    for method in METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = solve(mdp, method, tol=TOL)
        assert res.converged, (family, method)
        err = float(np.max(np.abs(res.v - ref.v)))
        if res.error_bound is not None:
            # the stated bound holds (plus the oracle's own rounding)
            assert err <= res.error_bound + 1e-9 * scale, (family, method, err, res.error_bound)
        # gamma = 1 sweeps have no a-priori bound; LP has HiGHS's tolerance
        allowed = TOL if mdp.gamma < 1 and method != "lp" else 1e-6 * scale
        assert err <= allowed + 1e-9 * scale, (family, method, err)
        # and the returned policy is optimal (and proper at gamma = 1)
        v_pi = pl.evaluate_policy(mdp, res.policy)
        assert np.max(ref.v - v_pi) <= 1e-6 * scale, (family, method)
        if method == "auto":
            assert res.method.startswith("auto: ")
            assert res.info["auto"]["method"] in METHODS
            assert res.info["auto"]["reason"]


def test_closed_forms_of_the_shortest_path_families() -> None:
    grid = slip_gridworld(9, 0.25, gamma=1.0)
    r, c = np.divmod(np.arange(81), 9)
    assert np.allclose(solve(grid).v, -((8 - r) + (8 - c)) / 0.75, atol=1e-9)
    chain = long_chain(40, 0.5, gamma=1.0)
    assert np.allclose(solve(chain).v, -(40 - np.arange(41)) / 0.5, atol=1e-9)
    # gamma < 1 on the chain: v(s) = -(1 - b^d) / (1 - gamma) with b the discount of one
    # step of progress, b = gamma p / (1 - gamma (1 - p)), d the steps left.
    g, p = 0.9, 0.5
    chain = long_chain(30, p, gamma=g)
    b = g * p / (1 - g * (1 - p))
    d = 30 - np.arange(31)
    want = -(1 - b**d) / (1 - b) / (1 - g * (1 - p))
    assert np.allclose(solve(chain, "vi-gs", tol=1e-12).v, want, atol=1e-9)


def test_auto_rules() -> None:
    assert choose_method(slip_gridworld(5, gamma=0.99))[0] == "vi-gs"
    assert choose_method(slip_gridworld(5, gamma=1.0))[0] == "pi"
    assert choose_method(random_mdp(100))[0] == "pi"
    assert choose_method(random_mdp(6000, 2, 2))[0] == "vi"
    assert choose_method(random_mdp(6000, 2, 2, gamma=0.999))[0] == "mpi"
    # rows that repeat (the next stock depends on s + a only; Jack's cars after the move):
    # the inventory's first policy cycles only through low stock levels (small strongly
    # connected components, cheap exact evaluation); Jack's mixes every state
    method, reason = choose_method(inventory_management(capacity=15))
    assert method == "pi" and "components" in reason
    method, reason = choose_method(jacks_car_rental(max_cars=6, max_move=2))
    assert method == "mpi" and "distinct" in reason
    # gamma given to solve overrides the MDP's
    assert choose_method(slip_gridworld(5, gamma=0.99), 1.0)[0] == "pi"
    with pytest.raises(InvalidArgumentError, match="method must be one of"):
        solve(random_mdp(5, 2, 2), "fastest")


def test_ordered_sweeps_are_few_on_episodic_tasks() -> None:
    mdp = slip_gridworld(30, 0.1, gamma=0.99)
    ordered = pl.value_iteration(mdp, tol=1e-8, gauss_seidel=True)
    plain = pl.value_iteration(mdp, tol=1e-8)
    assert np.max(np.abs(ordered.v - plain.v)) <= 2e-8
    assert ordered.iterations <= 5 < plain.iterations
    index = pl.value_iteration(mdp, tol=1e-8, gauss_seidel=True, order="index")
    assert np.max(np.abs(index.v - plain.v)) <= 2e-8
    perm = np.random.default_rng(0).permutation(mdp.n_states)
    mixed = pl.value_iteration(mdp, tol=1e-8, gauss_seidel=True, order=perm)
    assert np.max(np.abs(mixed.v - plain.v)) <= 2e-8
    with pytest.raises(InvalidArgumentError, match="permutation"):
        pl.value_iteration(mdp, gauss_seidel=True, order=np.zeros(mdp.n_states, dtype=int))
    with pytest.raises(InvalidArgumentError, match="order must be"):
        pl.value_iteration(mdp, gauss_seidel=True, order="backwards")
    with pytest.raises(InvalidArgumentError, match="gauss_seidel=True"):
        pl.value_iteration(mdp, order="index")


def test_family_builders_check_their_arguments() -> None:
    with pytest.raises(InvalidArgumentError, match="size"):
        slip_gridworld(1)
    with pytest.raises(InvalidArgumentError, match="slip"):
        slip_gridworld(4, slip=1.0)
    with pytest.raises(InvalidArgumentError, match="success"):
        long_chain(4, success=0.0)
    with pytest.raises(InvalidArgumentError, match="n_states"):
        long_chain(0)
    assert pl.problems.get_problem("slip-gridworld", size=3).n_states == 9
    assert pl.problems.get_problem("long-chain", n_states=3).n_states == 4


#: The families that the benchmark also solves as post-decision models (small sizes).
POST_DECISION = {
    "inventory": {"capacity": 15},
    "inventory-max-order": {"capacity": 40, "max_order": 8},
    "jacks-car-rental": {"max_cars": 6, "max_move": 2},
    "jacks-car-rental-8": {"max_cars": 8, "max_move": 3},
}


@pytest.mark.parametrize("family", sorted(POST_DECISION))
def test_every_post_decision_method_reaches_the_optimum(family: str) -> None:
    kw = POST_DECISION[family]
    build = jacks_car_rental if family.startswith("jacks") else inventory_management
    model, table = build(**kw, post_decision=True), build(**kw)
    ref = pl.policy_iteration(table, solver="direct")
    scale = max(1.0, float(np.abs(ref.v).max()))
    for method in ("auto", "vi", "pi", "mpi"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            res = solve(model, method, tol=TOL)
        assert res.converged, (family, method)
        err = float(np.max(np.abs(res.v - ref.v)))
        assert res.error_bound is not None
        assert err <= res.error_bound + 1e-9 * scale, (family, method, err, res.error_bound)
        assert err <= TOL + 1e-9 * scale, (family, method, err)
        v_pi = pl.evaluate_policy(table, pl.Policy.from_actions(table, res.policy.action_indices()))
        assert np.max(ref.v - v_pi) <= 1e-6 * scale, (family, method)
    # the inventory's policies split into small components: auto is policy iteration
    # with evaluation by components; Jack's Kronecker kernel goes to adaptive MPI
    chosen, reason = choose_method(model)
    assert chosen == ("mpi" if family.startswith("jacks") else "pi"), reason
    if chosen == "pi":
        assert solve(model).info["solver"].startswith("direct (components")


def test_auto_on_a_post_decision_model_with_one_large_component_is_mpi() -> None:
    import scipy.sparse as sp

    from policylab.mdp import PostDecisionMDP

    rng = np.random.default_rng(0)
    S, A = 400, 2
    K = sp.random_array((S, S), density=0.02, random_state=rng, format="csr")
    K = sp.csr_array(K + sp.eye_array(S, k=1, format="csr") + sp.eye_array(S, k=1 - S))
    K = sp.csr_array(K.multiply(1.0 / K.sum(axis=1)[:, None]))  # a cycle through all
    model = PostDecisionMDP(rng.integers(0, S, (S, A)), rng.normal(size=(S, A)), K, 0.9)
    chosen, reason = choose_method(model)
    assert chosen == "mpi", reason
    ref = solve(model, "pi", tol=1e-10)
    res = solve(model, tol=1e-8)
    assert np.max(np.abs(res.v - ref.v)) <= res.error_bound + 1e-9
