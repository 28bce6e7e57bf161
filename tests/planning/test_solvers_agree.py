"""Every solver against the brute-force optimum and the dense linear solve (hypothesis)."""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import policylab as pl
from policylab.planning import linear_programming, modified_policy_iteration

from .conftest import brute_force_optimum, dense_policy_value, small_random_mdp

mdps = st.builds(
    lambda seed, S, A, g, epi: (small_random_mdp(seed, S, A, g, epi), g),
    st.integers(0, 10_000),
    st.integers(1, 4),
    st.integers(1, 3),
    st.sampled_from([0.0, 0.5, 0.9, 0.99]),
    st.booleans(),
) | st.builds(
    lambda seed, S, A: (small_random_mdp(seed, S, A, 1.0, True), 1.0),
    st.integers(0, 10_000),
    st.integers(1, 4),
    st.integers(1, 3),
)


@settings(max_examples=40, deadline=None)
@given(mdps)
def test_all_solvers_reach_the_brute_force_optimum(case: tuple[pl.FiniteMDP, float]) -> None:
    mdp, g = case
    v_star = brute_force_optimum(mdp, g)
    tol = 1e-8
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        results = [
            pl.value_iteration(mdp, tol=tol),
            pl.value_iteration(mdp, tol=tol, gauss_seidel=True),
            pl.policy_iteration(mdp),
            pl.policy_iteration(mdp, solver="krylov"),
            pl.policy_iteration(mdp, evaluation="iterative", tol=1e-11),
            modified_policy_iteration(mdp, tol=tol, m=3),
        ]
    lp = linear_programming(mdp)
    scale = max(1.0, float(np.abs(v_star).max()))
    assert np.allclose(lp.v, v_star, atol=1e-6 * scale)
    assert np.allclose(dense_policy_value(mdp, lp.policy.probs, g), v_star, atol=1e-6 * scale)
    for res in results:
        assert res.converged
        scale = max(1.0, float(np.abs(v_star).max()))
        # gamma = 1 has no a-priori bound: the sweeps stop on a small change.
        allowed = tol if g < 1 else 1e-6 * scale
        assert np.max(np.abs(res.v - v_star)) <= allowed + 1e-12 * scale, res
        if res.error_bound is not None:
            assert np.max(np.abs(res.v - v_star)) <= res.error_bound + 1e-12 * scale
        # The returned policy is optimal: its exact value is v_*.
        v_pi = dense_policy_value(mdp, res.policy.probs, g)
        assert np.allclose(v_pi, v_star, atol=1e-6 * scale)


@settings(max_examples=40, deadline=None)
@given(mdps, st.integers(0, 1000))
def test_evaluation_matches_dense_solve(case: tuple[pl.FiniteMDP, float], seed: int) -> None:
    mdp, g = case
    rng = np.random.default_rng(seed)
    probs = rng.random((mdp.n_states, mdp.n_actions)) * mdp.action_mask
    probs[mdp.terminal] = 0
    rows = probs.sum(axis=1, keepdims=True)
    probs = np.divide(probs, rows, out=np.zeros_like(probs), where=rows > 0)
    pi = pl.Policy.from_array(mdp, probs)
    oracle = dense_policy_value(mdp, pi.probs, g)
    scale = max(1.0, float(np.abs(oracle).max()))
    for kwargs in (
        {"method": "exact"},
        {"method": "exact", "solver": "krylov"},
        {"method": "iterative", "tol": 1e-10},
        {"method": "iterative", "tol": 1e-10, "in_place": True},
    ):
        v = pl.evaluate_policy(mdp, pi, **kwargs)  # type: ignore[call-overload]
        assert np.allclose(v, oracle, atol=1e-8 * scale), kwargs
    # q_pi from v_pi satisfies v_pi = sum_a pi q_pi.
    q = pl.action_values(mdp, oracle, gamma=g)
    assert np.allclose(pl.planning.state_values(mdp, q, pi), oracle, atol=1e-9 * scale)


def test_krylov_and_direct_evaluation_agree_on_a_larger_random_mdp() -> None:
    from policylab.problems import random_mdp

    mdp = random_mdp(3000, 3, 8, seed=5, gamma=0.99)
    rng = np.random.default_rng(0)
    det = pl.Policy.from_actions(mdp, rng.integers(0, 3, mdp.n_states))
    for pi in (det, pl.Policy.uniform(mdp)):
        direct = pl.evaluate_policy(mdp, pi, solver="direct", return_result=True)
        krylov = pl.evaluate_policy(mdp, pi, solver="krylov", return_result=True)
        assert krylov.info["solver"].startswith("krylov")
        assert krylov.error_bound is not None
        assert np.max(np.abs(krylov.v - direct.v)) <= krylov.error_bound + 1e-9
        assert np.max(np.abs(krylov.v - direct.v)) <= 1e-7
    res = pl.policy_iteration(mdp, solver="krylov")
    vi = pl.value_iteration(mdp, tol=1e-7)
    assert vi.error_bound is not None and vi.error_bound <= 1e-7
    assert np.max(np.abs(vi.v - res.v)) <= 1e-7
    assert np.array_equal(vi.policy.action_indices(), res.policy.action_indices())


def test_krylov_at_gamma_one_does_not_accept_a_large_residual() -> None:
    # Found by hypothesis: the gamma = 1 residual target once scaled with 1 / (1 - gamma).
    mdp = small_random_mdp(337, 3, 3, 1.0, episodic=True)
    krylov = pl.policy_iteration(mdp, solver="krylov")
    direct = pl.policy_iteration(mdp, solver="direct")
    assert np.allclose(krylov.v, direct.v, atol=1e-9)
    assert krylov.residual < 1e-9


def test_auto_solver_sweeps_above_the_direct_size() -> None:
    from policylab.planning.evaluation import DIRECT_MAX_STATES
    from policylab.problems import random_mdp

    mdp = random_mdp(DIRECT_MAX_STATES + 500, 2, 6, seed=3, gamma=0.9)
    pi = pl.Policy.from_actions(mdp, np.zeros(mdp.n_states, dtype=np.int64))
    auto = pl.evaluate_policy(mdp, pi, return_result=True)
    assert auto.info["solver"].startswith("sweeps")
    assert auto.error_bound is not None
    # The oracle: any x with Bellman residual rho = r_pi + gamma P_pi x - x satisfies
    # max|x - v_pi| <= max|rho| / (1 - gamma). A Krylov solve gives an x whose residual,
    # recomputed here from the transition matrix, certifies it to about 1e-14 (a sparse
    # LU of this random graph fills in and takes a minute).
    x = pl.evaluate_policy(mdp, pi, solver="krylov")
    P = mdp.transition_matrix[np.arange(mdp.n_states) * mdp.n_actions]  # action 0's rows
    rho = mdp.expected_reward[:, 0] + 0.9 * (P @ x) - x
    certified = float(np.abs(rho).max()) / (1 - 0.9)
    assert certified < 1e-11
    assert np.max(np.abs(auto.v - x)) + certified <= auto.error_bound + 1e-12
