"""PostDecisionMDP: the same v_*, policy and bounds as the outcome table of the same MDP."""

from __future__ import annotations

import numba
import numpy as np
import pytest
import scipy.sparse as sp

import policylab as pl
from policylab.exceptions import InvalidArgumentError, InvalidMDPError, ShapeError
from policylab.mdp import PostDecisionKernel, PostDecisionMDP
from policylab.planning import postdecision
from policylab.planning.auto import choose_method, solve
from policylab.problems import inventory_management, jacks_car_rental

JACK = {"max_cars": 6, "max_move": 2}
INVENTORY = {"capacity": 15, "max_order": 6}


@pytest.fixture(scope="module")
def pairs() -> dict[str, tuple[PostDecisionMDP, pl.FiniteMDP, np.ndarray]]:
    """Each problem as a post-decision model, as the outcome table and its exact v_*."""
    out = {}
    for name, build, kw in (
        ("jacks", jacks_car_rental, JACK),
        ("inventory", inventory_management, INVENTORY),
    ):
        pd_model = build(**kw, post_decision=True)
        table = build(**kw)
        out[name] = (pd_model, table, pl.policy_iteration(table).v)
    return out


@pytest.mark.parametrize("name", ["jacks", "inventory"])
@pytest.mark.parametrize("method", ["auto", "vi", "pi", "mpi"])
def test_same_optimum_policy_and_bound_as_the_table(name: str, method: str, pairs: dict) -> None:
    model, table, v_star = pairs[name]
    res = solve(model, method, tol=1e-7)
    ref = solve(table, method if method != "auto" else "pi", tol=1e-7)
    assert res.converged
    assert res.error_bound is not None and res.error_bound <= 1e-7 + 1e-9
    # the proven bound holds against the exact optimum of the outcome table
    assert np.max(np.abs(res.v - v_star)) <= res.error_bound + 1e-9
    np.testing.assert_array_equal(res.policy.action_indices(), ref.policy.action_indices())
    np.testing.assert_allclose(res.q, ref.q, rtol=1e-9, atol=1e-6)
    if method == "auto":
        # the inventory's policies cycle only through low stock levels (small strongly
        # connected components: exact evaluation is cheap); Jack's kernel is a product
        assert res.info["auto"]["method"] == {"jacks": "mpi", "inventory": "pi"}[name]


@pytest.mark.parametrize("name", ["jacks", "inventory"])
def test_value_iteration_takes_the_same_sweeps_and_bound(name: str, pairs: dict) -> None:
    model, table, _ = pairs[name]
    a = pl.value_iteration(model, tol=1e-8)
    b = pl.value_iteration(table, tol=1e-8)
    assert a.iterations == b.iterations
    assert a.error_bound == pytest.approx(b.error_bound, rel=1e-6)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-9)


@pytest.mark.parametrize("name", ["jacks", "inventory"])
def test_to_finite_mdp_is_the_same_table(name: str, pairs: dict) -> None:
    model, table, v_star = pairs[name]
    flat = model.to_finite_mdp()
    assert flat.n_outcomes == model.n_outcomes
    np.testing.assert_allclose(flat.expected_reward, table.expected_reward, atol=1e-9)
    for a in table.actions:
        np.testing.assert_allclose(
            flat.transitions(a).toarray(), table.transitions(a).toarray(), atol=1e-12
        )
    np.testing.assert_allclose(pl.policy_iteration(flat).v, v_star, atol=1e-8)


def test_jacks_classic_size_reproduces_figure_4_2() -> None:
    # the outcome table's policy iteration checks the same figures (test_planning_problems)
    model = jacks_car_rental(post_decision=True)
    res = pl.policy_iteration(model)
    assert res.error_bound is not None and res.error_bound < 1e-8
    assert res.v.min() == pytest.approx(421, abs=1)  # bottom of Figure 4.2's v_4 (420)
    acts = np.asarray(model.actions)[res.policy.action_indices()].reshape(21, 21)
    assert acts[20, 0] == 5 and acts[0, 20] == -4 and acts[10, 10] == 0  # pi_4's corners


def test_kronecker_kernel_equals_the_formed_product() -> None:
    rng = np.random.default_rng(0)
    f1 = rng.random((3, 4))
    f2 = rng.random((5, 2))
    f3 = rng.random((2, 3))
    facs = [f / f.sum(axis=1, keepdims=True) for f in (f1, f2, f3)]
    full = np.kron(np.kron(facs[0], facs[1]), facs[2])
    v = rng.random(full.shape[1])
    for kern in (
        PostDecisionKernel(*facs),
        PostDecisionKernel(facs[0], sp.csr_array(facs[1]), facs[2]),
    ):
        np.testing.assert_allclose(kern.expect(v), full @ v, rtol=1e-13)
        np.testing.assert_allclose(kern.to_csr().toarray(), full, rtol=1e-13)
        ys = np.array([0, 7, 29])
        np.testing.assert_allclose(kern.dense_rows(ys), full[ys], rtol=1e-13)
    two = PostDecisionKernel(facs[0], facs[1])
    np.testing.assert_allclose(two.expect(v[:8]), np.kron(facs[0], facs[1]) @ v[:8], rtol=1e-13)


def test_threads_give_identical_backups() -> None:
    # 186,624 states x 11 actions: above the size where sweeps go to the threaded kernel
    model = jacks_car_rental(max_cars=431, post_decision=True)
    v = np.random.default_rng(1).random(model.n_states) * 100
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = postdecision.optimality_backup(model, 0.9, v)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = postdecision.optimality_backup(model, 0.9, v)
    finally:
        numba.set_num_threads(old)
    np.testing.assert_array_equal(one[0], two[0])
    np.testing.assert_array_equal(one[1], two[1])


def _tiny(**kw: object) -> PostDecisionMDP:
    args: dict = {
        "post": np.array([[0, 1], [1, 0]]),
        "reward": np.array([[1.0, 0.0], [0.0, 2.0]]),
        "kernel": np.array([[0.5, 0.5], [0.2, 0.8]]),
        "gamma": 0.9,
    }
    args.update(kw)
    return PostDecisionMDP(args.pop("post"), args.pop("reward"), args.pop("kernel"), **args)


def test_tiny_model_matches_a_linear_solve() -> None:
    model = _tiny()
    res = pl.policy_iteration(model)
    acts = res.policy.action_indices()
    K = np.array([[0.5, 0.5], [0.2, 0.8]])
    P = K[model.post[np.arange(2), acts]]
    r = model.reward[np.arange(2), acts]
    np.testing.assert_allclose(res.v, np.linalg.solve(np.eye(2) - 0.9 * P, r), atol=1e-12)
    v_pi = pl.evaluate_policy(model, res.policy, return_result=True)
    np.testing.assert_allclose(v_pi.v, res.v, atol=1e-12)
    assert v_pi.error_bound is not None and v_pi.error_bound < 1e-12
    with pytest.raises(InvalidArgumentError, match="deterministic"):
        pl.evaluate_policy(model, pl.Policy.uniform(model))
    with pytest.raises(InvalidArgumentError, match="exact"):
        pl.evaluate_policy(model, res.policy, method="iterative")
    assert model.available_actions(1) == [0, 1]
    assert "PostDecisionMDP" in repr(model)


@pytest.mark.parametrize(
    ("kw", "error", "words"),
    [
        ({"kernel": np.array([[0.5, 0.4], [0.2, 0.8]])}, InvalidMDPError, "row 0 of the kernel"),
        ({"kernel": np.array([[1.5, -0.5], [0.2, 0.8]])}, InvalidMDPError, "negative"),
        ({"kernel": np.ones((2, 3)) / 3}, ShapeError, "3 states"),
        ({"post": np.array([[0, 2], [1, 0]])}, InvalidMDPError, "is not a post-decision"),
        ({"post": np.array([[0.0, 1.0], [1.0, 0.0]])}, InvalidMDPError, "integer"),
        ({"reward": np.ones((2, 3))}, ShapeError, "reward"),
        ({"reward": np.array([[np.nan, 0.0], [0.0, 2.0]])}, InvalidMDPError, "finite"),
        (
            {"action_mask": np.array([[True, True], [False, False]])},
            InvalidMDPError,
            "no available action",
        ),
        ({"gamma": 1.5}, InvalidArgumentError, "gamma"),
    ],
)
def test_bad_models_are_refused(kw: dict, error: type, words: str) -> None:
    with pytest.raises(error, match=words):
        _tiny(**kw)


def test_bad_solver_options_are_refused() -> None:
    model = _tiny()
    with pytest.raises(InvalidArgumentError, match="continuing task"):
        pl.value_iteration(model, gamma=1.0)
    with pytest.raises(InvalidArgumentError, match="gauss_seidel"):
        pl.value_iteration(model, gauss_seidel=True)
    with pytest.raises(InvalidArgumentError, match="outcome table"):
        solve(model, "lp")
    with pytest.raises(InvalidArgumentError, match="max_outcomes"):
        model.to_finite_mdp(max_outcomes=3)
    with pytest.raises(InvalidArgumentError, match="post_decision=True"):
        jacks_car_rental(max_cars=200)
    with pytest.raises(InvalidArgumentError, match="max_cars"):
        jacks_car_rental(max_cars=0, post_decision=True)
    with pytest.raises(InvalidArgumentError, match="max_order"):
        inventory_management(max_order=-1)
    assert choose_method(model)[0] == "mpi"
