"""Policy evaluation by strongly connected components, against a dense linear solve."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import policylab as pl
from policylab.planning import postdecision
from policylab.planning._kernels import dense_block_max, solve_by_components
from policylab.planning.evaluation import solve_policy_system
from policylab.problems import inventory_management


def planted_components(seed: int, sizes: list[int]) -> tuple[sp.csr_array, np.ndarray]:
    """A substochastic CSR matrix whose graph has cycles of the given sizes, each able to
    reach some of the others, with the states shuffled (components out of index order)."""
    rng = np.random.default_rng(seed)
    n = sum(sizes)
    perm = rng.permutation(n)
    groups = np.split(perm, np.cumsum(sizes)[:-1])
    dense = np.zeros((n, n))
    for g, members in enumerate(groups):
        for i, s in enumerate(members):
            dense[s, members[(i + 1) % len(members)]] += 0.5  # a cycle (or a self-loop)
            if g > 0:  # and an edge to an earlier component
                dense[s, rng.choice(np.concatenate(groups[:g]))] += 0.3
            else:
                dense[s, s] += 0.2
    return sp.csr_array(dense), rng.normal(size=n)


@pytest.mark.parametrize("sizes", [[1] * 12, [3, 1, 4, 1, 5], [2, 7, 1, 1, 3, 6], [30]])
@pytest.mark.parametrize("gamma", [0.5, 0.99])
def test_matches_the_dense_solve(sizes: list[int], gamma: float) -> None:
    P, b = planted_components(len(sizes), sizes)
    n = P.shape[0]
    found = solve_by_components(
        P.indptr, P.indices, P.data, np.arange(n), b, gamma, max_block=max(sizes)
    )
    assert found is not None
    x, largest = found
    assert largest == max(sizes)
    exact = np.linalg.solve(np.eye(n) - gamma * P.toarray(), b)
    np.testing.assert_allclose(x, exact, rtol=1e-12, atol=1e-12)


def test_too_large_a_component_and_a_pure_self_loop_at_gamma_1_are_refused() -> None:
    P, b = planted_components(0, [3, 5])
    n = P.shape[0]
    assert solve_by_components(P.indptr, P.indices, P.data, np.arange(n), b, 0.9, 4) is None
    loop = sp.csr_array(np.array([[1.0, 0.0], [0.5, 0.5]]))
    got = solve_by_components(loop.indptr, loop.indices, loop.data, np.arange(2), b[:2], 1.0, 1)
    assert got is None


def test_rows_without_dynamics_are_zero_and_rows_may_repeat() -> None:
    # row_of maps states to rows (two states share row 0; -1 has no row: x = 0)
    K = sp.csr_array(np.array([[0.0, 0.5, 0.5], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]))
    row_of = np.array([0, 0, -1])
    b = np.array([1.0, 2.0, 5.0])
    x, largest = solve_by_components(K.indptr, K.indices, K.data, row_of, b, 0.9, 1)  # type: ignore[misc]
    # x2 = 0 (no row), x1 = 2 + 0.9 (0.5 x1), x0 = 1 + 0.9 (0.5 x1)
    x1 = 2.0 / (1 - 0.45)
    np.testing.assert_allclose(x, [1.0 + 0.45 * x1, x1, 0.0], rtol=1e-14)
    assert largest == 1


def test_inventory_policies_split_into_small_components() -> None:
    # outcome table: evaluation of the optimal (s, S) policy by components equals the LU
    mdp = inventory_management(capacity=40, max_order=12)
    acts = np.asarray(pl.policy_iteration(mdp).policy.action_indices())
    r_pi = mdp.expected_reward[np.arange(mdp.n_states), acts]
    x, info = solve_policy_system(mdp, None, r_pi, mdp.gamma, actions=acts)
    assert info["solver"].startswith("direct (components")
    lu, _ = solve_policy_system(mdp, None, r_pi, mdp.gamma, actions=acts, solver="direct")
    np.testing.assert_allclose(x, lu, rtol=1e-12, atol=1e-10)
    assert info["error_bound"] <= 1e-9


def test_post_decision_evaluation_by_components_equals_the_dense_lu(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    model = inventory_management(capacity=60, max_order=10, post_decision=True)
    acts = np.asarray(postdecision.policy_iteration(model).policy.action_indices())
    v, info = postdecision.evaluate_actions(model, acts, model.gamma)
    assert info["solver"].startswith("direct (components")
    assert info["error_bound"] <= 1e-9
    monkeypatch.setattr(postdecision, "dense_block_max", lambda _: 0)  # components refused
    dense, info2 = postdecision.evaluate_actions(model, acts, model.gamma)
    assert info2["solver"] == "dense LU"
    np.testing.assert_allclose(v, dense, rtol=1e-12, atol=1e-10)


def test_dense_block_max_keeps_the_block_no_larger_than_the_model() -> None:
    assert dense_block_max(8 * 100**2) == 100
    assert dense_block_max(8 * 100**2 - 1) == 99
    assert dense_block_max(10**12) == 3000
    assert dense_block_max(0) == 0


def test_small_components_accepts_cheap_splits_only() -> None:
    from policylab.planning._kernels import small_components
    from policylab.problems import jacks_car_rental

    # 12 single states, or cycles of up to 5 states among 30 single ones: the largest
    # LU (5^3 / 3 multiply-adds) costs less than a pass over the 90-odd entries
    for sizes, want in (([1] * 12, 1), ([3, 1, 4, 1, 5] + [1] * 30, 5)):
        P, _ = planted_components(0, sizes)
        n = P.shape[0]
        got = small_components(P.indptr, P.indices, P.data, np.arange(n), 10**9)
        assert got == want
    # one cycle of 30: 30^3 / 3 = 9,000 multiply-adds against 60 entries
    P, _ = planted_components(0, [30])
    assert small_components(P.indptr, P.indices, P.data, np.arange(30), 10**9) is None
    # a component over the dense-block limit (the model's size) is not small either
    P, _ = planted_components(0, [3, 5])
    assert small_components(P.indptr, P.indices, P.data, np.arange(8), 8 * 4**2) is None
    # Jack's car rental: every state in one component (rental and returns mix them)
    mdp = jacks_car_rental(max_cars=6, max_move=2)
    rows = np.arange(mdp.n_states) * mdp.n_actions + mdp.n_actions // 2  # move no car
    assert small_components(mdp.indptr, mdp.next_states, mdp.probs, rows, mdp.nbytes) is None
