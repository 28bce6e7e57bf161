"""1 and 2 threads: every method reaches the same optimum, within its bound, with the same numbers.

The thresholds above which the solvers split their passes over numba's threads are set
to 0 here, so that the threaded code runs at these small sizes; block Gauss-Seidel
sweeps (Jacobi between blocks, Gauss-Seidel inside each) are checked against the exact
optimum and against the plain sweep.
"""

from __future__ import annotations

import warnings

import numba
import numpy as np
import pytest

import policylab as pl
from policylab.planning import METHODS, _kernels, control, solve
from policylab.problems import inventory_management, jacks_car_rental, random_mdp
from policylab.problems.generators import long_chain, slip_gridworld

TOL = 1e-8
TWO = numba.config.NUMBA_NUM_THREADS >= 2


def _random_episodic(n: int = 200, seed: int = 5) -> pl.FiniteMDP:
    # A random sparse MDP whose last state is terminal and reachable from every state:
    # states at one distance from it are often neighbours (unlike a grid's).
    rng = np.random.default_rng(seed)
    A = 3
    P = np.zeros((A, n, n))
    for a in range(A):
        for s in range(n - 1):
            nxt = rng.choice(n, size=4, replace=False)
            P[a, s, nxt] = rng.random(4) + 0.05
        P[a, : n - 1, n - 1] += 0.02
        P[a] /= np.maximum(P[a].sum(axis=1, keepdims=True), 1e-300)
    R = rng.normal(-1.0, 1.0, size=(n, A))
    terminal = np.zeros(n, dtype=bool)
    terminal[-1] = True
    return pl.FiniteMDP.from_arrays(P, R, gamma=0.95, terminal=terminal)


FAMILIES = {
    "random": lambda: random_mdp(300, 4, 5, seed=3, gamma=0.95),
    "random-episodic": _random_episodic,
    "grid-0.99": lambda: slip_gridworld(12, 0.1, gamma=0.99),
    "grid-0.999": lambda: slip_gridworld(12, 0.2, gamma=0.999),
    "grid-shortest-path": lambda: slip_gridworld(12, 0.1, gamma=1.0),
    "chain-0.999": lambda: long_chain(150, 0.8, gamma=0.999),
    "inventory": lambda: inventory_management(capacity=15),
    "jacks-car-rental": lambda: jacks_car_rental(max_cars=6, max_move=2),
}


def _threads(monkeypatch: pytest.MonkeyPatch, threads: int) -> None:
    monkeypatch.setattr(_kernels, "PARALLEL_MIN_OUTCOMES", 0)
    monkeypatch.setattr(_kernels, "BLOCK_MIN_OUTCOMES", 0)
    monkeypatch.setattr(control, "BLOCK_MIN_OUTCOMES", 0)
    numba.set_num_threads(threads)


@pytest.mark.skipif(not TWO, reason="needs 2 numba threads")
@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_every_method_gives_the_same_optimum_on_1_and_2_threads(
    family: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    mdp = FAMILIES[family]()
    ref = pl.policy_iteration(mdp, solver="direct")
    scale = max(1.0, float(np.abs(ref.v).max()))
    before = numba.get_num_threads()
    runs: dict[int, dict[str, pl.PlanningResult]] = {}
    try:
        for threads in (1, 2):
            _threads(monkeypatch, threads)
            runs[threads] = {}
            for method in METHODS:
                if method == "lp":
                    continue
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    runs[threads][method] = solve(mdp, method, tol=TOL)
    finally:
        numba.set_num_threads(before)
    for method, one in runs[1].items():
        two = runs[2][method]
        assert one.converged and two.converged, (family, method)
        # deterministic in their ordering: the same numbers on 1 and 2 threads
        np.testing.assert_array_equal(one.v, two.v, err_msg=f"{family} {method}")
        np.testing.assert_array_equal(one.policy.probs, two.policy.probs)
        assert one.iterations == two.iterations
        err = float(np.max(np.abs(two.v - ref.v)))
        if two.error_bound is not None:
            assert err <= two.error_bound + 1e-9 * scale, (family, method, err)
        allowed = TOL if mdp.gamma < 1 else 1e-6 * scale
        assert err <= allowed + 1e-9 * scale, (family, method, err)
        v_pi = pl.evaluate_policy(mdp, two.policy)
        assert np.max(ref.v - v_pi) <= 1e-6 * scale, (family, method)


@pytest.mark.parametrize("build", [_random_episodic, lambda: slip_gridworld(15, 0.1, gamma=0.95)])
@pytest.mark.parametrize("n_blocks", [1, 2, 3, 7])
def test_block_sweeps_contract_to_the_optimum_within_their_bound(
    build: object, n_blocks: int
) -> None:
    mdp = build()  # type: ignore[operator]
    ref = pl.policy_iteration(mdp, solver="direct").v
    order, level = control._sweep_order(mdp, "terminal-first")
    assert level is not None
    blocks = _kernels.sweep_blocks(mdp, order, level, n_blocks)
    # the split: every state once, the blocks' bounds cover the order
    assert np.array_equal(np.sort(blocks.order), np.arange(mdp.n_states))
    assert blocks.bounds[0] == 0 and blocks.bounds[-1] == mdp.n_states
    g = mdp.gamma
    v = np.zeros(mdp.n_states)
    u = np.full(mdp.n_states, -50.0)
    u[mdp.terminal] = 0.0
    for _ in range(400):
        e = float(np.max(np.abs(u - v)))
        dv = _kernels.gauss_seidel_optimality_sweep(mdp, g, v, blocks=blocks)
        _kernels.gauss_seidel_optimality_sweep(mdp, g, u, blocks=blocks)
        # a gamma-contraction: two runs come gamma closer each sweep
        assert float(np.max(np.abs(u - v))) <= g * e + 1e-12
        # the sweep's change bounds the distance to v_*
        assert float(np.max(np.abs(v - ref))) <= g / (1 - g) * dv + 1e-9
        if g / (1 - g) * dv <= 1e-10:
            break
    assert float(np.max(np.abs(v - ref))) <= 1e-9


def test_one_block_is_the_plain_sweep() -> None:
    mdp = _random_episodic()
    order, level = control._sweep_order(mdp, "terminal-first")
    assert level is not None
    one = _kernels.sweep_blocks(mdp, order, level, 1)
    v = np.zeros(mdp.n_states)
    w = np.zeros(mdp.n_states)
    for _ in range(5):
        d1 = _kernels.gauss_seidel_optimality_sweep(mdp, mdp.gamma, v, order)
        d2 = _kernels.gauss_seidel_optimality_sweep(mdp, mdp.gamma, w, blocks=one)
        assert d1 == d2
        np.testing.assert_array_equal(v, w)


@pytest.mark.parametrize("threads", [1, 2])
def test_compiled_greedy_policy_is_the_first_greedy_action(
    threads: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("needs 2 numba threads")
    mdp = jacks_car_rental(max_cars=6, max_move=2)  # A(s) depends on s
    assert not mdp.action_mask.all()
    rng = np.random.default_rng(0)
    # values with exact ties, near-ties within the tolerance, and unavailable actions
    q = rng.integers(-3, 3, size=(mdp.n_states, mdp.n_actions)).astype(np.float64)
    q += rng.choice([0.0, 1e-12, 1e-3], size=q.shape)
    before = numba.get_num_threads()
    try:
        _threads(monkeypatch, threads)
        pol = pl.greedy_policy(mdp, q)
    finally:
        numba.set_num_threads(before)
    want = pl.planning.greedy_actions(mdp, q)
    expect = np.zeros((mdp.n_states, mdp.n_actions))
    live = np.flatnonzero(~mdp.terminal)
    expect[live, want[live]] = 1.0
    np.testing.assert_array_equal(pol.probs, expect)
    assert not pol.probs.flags.writeable


@pytest.mark.parametrize("n_chunks", [2, 3, 8])
def test_reversed_graph_is_the_same_in_chunks(n_chunks: int) -> None:
    mdp = _random_episodic()
    flat = mdp.action_mask.reshape(-1).copy()
    flat[::5] = False  # some actions left out
    args = (mdp.indptr, mdp.next_states, mdp.probs, flat, mdp.n_states)
    start, src = _kernels._reversed_graph(*args, 1)
    # the oracle: every allowed (s, a, s') with p > 0, as edges s' <- s, sorted by (s', s)
    rows = np.repeat(np.arange(flat.shape[0]), np.diff(mdp.indptr))
    keep = flat[rows] & (mdp.probs > 0)
    pairs = sorted(
        zip(mdp.next_states[keep].tolist(), (rows[keep] // mdp.n_actions).tolist(), strict=True)
    )
    assert [s for _, s in pairs] == src.tolist()
    assert np.array_equal(
        np.diff(start), np.bincount(mdp.next_states[keep], minlength=mdp.n_states)
    )
    for kernel in (_kernels._reversed_graph, _kernels._reversed_graph_par):
        start_c, src_c = kernel(*args, n_chunks)
        np.testing.assert_array_equal(start_c, start)
        np.testing.assert_array_equal(src_c, src)


@pytest.mark.parametrize("threads", [1, 2])
def test_policy_improvement_keeps_tied_actions(
    threads: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    if threads > numba.config.NUMBA_NUM_THREADS:
        pytest.skip("needs 2 numba threads")
    mdp = jacks_car_rental(max_cars=6, max_move=2)
    rng = np.random.default_rng(2)
    q = rng.integers(-3, 3, size=(mdp.n_states, mdp.n_actions)).astype(np.float64)
    q += rng.choice([0.0, 1e-12, 1e-3], size=q.shape)
    q[~mdp.action_mask] = -np.inf
    current = np.array([rng.choice(np.flatnonzero(row)) for row in mdp.action_mask])
    before = numba.get_num_threads()
    try:
        _threads(monkeypatch, threads)
        new, changed = _kernels.improved_actions(mdp, q, current, 1e-9)
    finally:
        numba.set_num_threads(before)
    # the rule written out with NumPy
    best_a = q.argmax(axis=1)
    best = q[np.arange(mdp.n_states), best_a]
    keep = q[np.arange(mdp.n_states), current] >= best - 1e-9 * np.maximum(1.0, np.abs(best))
    want = np.where(keep, current, best_a)
    np.testing.assert_array_equal(new, want)
    assert changed == int(np.count_nonzero((want != current) & ~mdp.terminal))
    assert 0 < changed < mdp.n_states
