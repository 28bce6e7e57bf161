"""The fast paths of the sweeps give the same numbers as the plain ones.

Shared outcome rows, the threaded kernels, the dense LU of policy evaluation and
modified policy iteration with adaptive m are each checked against the plain
computation: bit for bit where the arithmetic is the same, against an exact linear
solve otherwise.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.planning import _kernels, modified_policy_iteration, solve, solve_policy_system
from policylab.planning._kernels import q_values, shared_rows
from policylab.problems import inventory_management, jacks_car_rental, random_mdp
from policylab.problems.generators import slip_gridworld

from .conftest import small_random_mdp


def _plain_q(mdp: pl.FiniteMDP, gamma: float, v: np.ndarray) -> np.ndarray:
    """q by the plain kernel (shared rows switched off for this model)."""
    saved = _kernels._SHARED.get(mdp, "absent")
    _kernels._SHARED[mdp] = None
    try:
        return q_values(mdp, gamma, v)
    finally:
        if saved == "absent":
            del _kernels._SHARED[mdp]
        else:
            _kernels._SHARED[mdp] = saved  # type: ignore[assignment]


@pytest.mark.parametrize(
    "build",
    [lambda: inventory_management(capacity=20), lambda: jacks_car_rental(max_cars=6, max_move=2)],
)
def test_shared_rows_are_the_models_rows_and_give_the_same_q(build: object) -> None:
    mdp = build()  # type: ignore[operator]
    sh = shared_rows(mdp)
    assert sh is not None
    assert sh.probs.shape[0] <= 0.5 * mdp.n_outcomes
    # every (s, a) row equals its distinct row, entry for entry
    for row in range(mdp.n_states * mdp.n_actions):
        lo, hi = mdp.indptr[row], mdp.indptr[row + 1]
        u = sh.row_of[row]
        ulo, uhi = sh.indptr[u], sh.indptr[u + 1]
        assert np.array_equal(mdp.next_states[lo:hi], sh.next_states[ulo:uhi])
        assert np.array_equal(mdp.probs[lo:hi], sh.probs[ulo:uhi])
    v = np.random.default_rng(0).normal(size=mdp.n_states) * 10
    assert np.array_equal(q_values(mdp, 0.9, v), _plain_q(mdp, 0.9, v))
    # and q_values matches the transition matrix
    want = mdp.expected_reward + 0.9 * (mdp.transition_matrix @ v).reshape(
        mdp.expected_reward.shape
    )
    got = q_values(mdp, 0.9, v)
    assert np.allclose(got[mdp.action_mask], want[mdp.action_mask], rtol=0, atol=1e-10)
    assert np.all(got[~mdp.action_mask] == -np.inf)


def test_models_without_repeated_rows_keep_the_plain_sweep() -> None:
    assert shared_rows(random_mdp(200, 3, 10, seed=1)) is None
    assert shared_rows(slip_gridworld(6)) is None  # rows too short to look


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 numba threads")
def test_threaded_sweeps_equal_the_sequential_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    mdps = [random_mdp(400, 3, 6, seed=2, gamma=0.95), inventory_management(capacity=12)]
    before = numba.get_num_threads()
    results = {}
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            monkeypatch.setattr(_kernels, "PARALLEL_MIN_OUTCOMES", 0)
            results[threads] = [
                (solve(m, "vi", tol=1e-10), solve(m, "mpi", tol=1e-10)) for m in mdps
            ]
    finally:
        numba.set_num_threads(before)
    for one, two in zip(results[1], results[2], strict=True):
        for a, b in zip(one, two, strict=True):
            assert a.iterations == b.iterations
            assert np.array_equal(a.v, b.v)
            assert np.array_equal(a.policy.probs, b.policy.probs)


def test_dense_lu_evaluation_matches_the_sparse_lu() -> None:
    mdp = jacks_car_rental(max_cars=6, max_move=2)
    acts = np.asarray(pl.greedy_policy(mdp, mdp.expected_reward).action_indices())
    r_pi = mdp.expected_reward[np.arange(mdp.n_states), acts]
    dense, info = solve_policy_system(mdp, None, r_pi, 0.9, actions=acts)
    assert info["solver"] == "direct (dense LU)"
    sparse, info_s = solve_policy_system(mdp, None, r_pi, 0.9, actions=acts, solver="direct")
    assert info_s["solver"] == "direct (sparse LU)"
    assert np.max(np.abs(dense - sparse)) <= 1e-10 * max(1.0, float(np.abs(sparse).max()))
    assert info["error_bound"] <= 1e-9


@pytest.mark.parametrize(
    "build",
    [
        lambda: random_mdp(150, 3, 5, seed=4, gamma=0.95),
        lambda: small_random_mdp(5, 12, 3, 0.99),
        lambda: small_random_mdp(6, 10, 3, 0.9, episodic=True),
        lambda: inventory_management(capacity=15),
        lambda: jacks_car_rental(max_cars=6, max_move=2),
    ],
)
def test_adaptive_m_reaches_the_optimum_within_its_bound(build: object) -> None:
    mdp = build()  # type: ignore[operator]
    ref = pl.policy_iteration(mdp, solver="direct")
    res = modified_policy_iteration(mdp, m="adaptive", tol=1e-8)
    assert res.converged
    assert res.error_bound is not None and res.error_bound <= 1e-8
    assert np.max(np.abs(res.v - ref.v)) <= res.error_bound + 1e-10
    assert np.max(ref.v - pl.evaluate_policy(mdp, res.policy)) <= 1e-8 * max(1, np.abs(ref.v).max())
    sweeps = res.info["evaluation_sweeps"]
    assert len(sweeps) == res.iterations - 1
    assert all(1 <= m <= 1000 for m in sweeps)


def test_adaptive_m_rejects_other_words() -> None:
    with pytest.raises(InvalidArgumentError, match="'adaptive'"):
        modified_policy_iteration(random_mdp(5, 2, 2), m="auto")


def test_back_substitution_solves_acyclic_policies_exactly() -> None:
    from policylab.planning import proper_policy

    for mdp, gamma in (
        (slip_gridworld(8, 0.2, gamma=1.0), 1.0),
        (slip_gridworld(8, 0.2, gamma=0.95), 0.95),
    ):
        acts = np.asarray(proper_policy(mdp).action_indices())
        r_pi = mdp.expected_reward[np.arange(mdp.n_states), acts]
        r_pi[mdp.terminal] = 0.0
        tri, info = solve_policy_system(mdp, None, r_pi, gamma, actions=acts)
        assert info["solver"] == "direct (back-substitution)"
        lu, _ = solve_policy_system(mdp, None, r_pi, gamma, actions=acts, solver="direct")
        assert np.max(np.abs(tri - lu)) <= 1e-10 * max(1.0, float(np.abs(lu).max()))
        assert info["residual"] <= 1e-10
    # a policy whose graph has cycles goes to the other solvers
    mdp = random_mdp(50, 2, 3, seed=0)
    acts = np.zeros(mdp.n_states, dtype=np.int64)
    _, info = solve_policy_system(mdp, None, mdp.expected_reward[:, 0], 0.9, actions=acts)
    assert info["solver"] != "direct (back-substitution)"


@pytest.mark.parametrize("threads", [1, 2])
def test_fused_optimality_values_equal_the_two_pass_sweep(
    threads: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # value iteration's one-pass T v (max taken as the rows are summed, -inf folded
    # into r) against the q-then-max sweep, bit for bit, with unavailable actions and
    # terminal states present; threaded too
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("needs 2 numba threads")
    monkeypatch.setattr(_kernels, "PARALLEL_MIN_OUTCOMES", 0 if threads > 1 else 10**12)
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        for mdp in (
            slip_gridworld(8, 0.1, gamma=0.95),
            small_random_mdp(7, 30, 4, 0.9, episodic=True),
            jacks_car_rental(max_cars=4, max_move=2),
        ):
            _kernels._SHARED[mdp] = None  # the plain path (shared rows tested above)
            v = np.random.default_rng(3).normal(size=mdp.n_states) * 10
            v[mdp.terminal] = 0.0
            two_pass, _ = _kernels.optimality_sweep(mdp, 0.95, v)
            np.testing.assert_array_equal(_kernels.optimality_values(mdp, 0.95, v), two_pass)
    finally:
        numba.set_num_threads(before)
