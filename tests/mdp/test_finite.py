"""FiniteMDP: constructors round-trip, derived views, sampling, and every bad-input case."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import scipy.sparse as sp

import policylab as pl
from policylab.exceptions import (
    InvalidArgumentError,
    InvalidMDPError,
    ShapeError,
    UnknownLabelError,
)


def robot_dynamics(alpha: float = 0.7, beta: float = 0.2) -> dict:
    return {
        "high": {
            "search": [(alpha, "high", 4.0), (1 - alpha, "low", 4.0)],
            "wait": [(1.0, "high", 1.0)],
        },
        "low": {
            "search": [(beta, "low", 4.0), (1 - beta, "high", -3.0)],
            "wait": [(1.0, "low", 1.0)],
            "recharge": [(1.0, "high", 0.0)],
        },
    }


def test_from_dynamics_round_trip():
    mdp = pl.FiniteMDP.from_dynamics(robot_dynamics(), gamma=0.9)
    assert mdp.states == ("high", "low")
    assert mdp.actions == ("search", "wait", "recharge")
    assert mdp.available_actions("high") == ["search", "wait"]
    assert mdp.available_actions("low") == ["search", "wait", "recharge"]
    for s, acts in robot_dynamics().items():
        for a, outs in acts.items():
            assert sorted(mdp.outcomes(s, a), key=str) == sorted(
                [(p, n, r) for p, n, r in outs], key=str
            )
    assert mdp.p("high", 4.0, "high", "search") == pytest.approx(0.7)
    # r(s, a) = sum p r, by hand
    np.testing.assert_allclose(
        mdp.expected_reward, [[4.0, 1.0, 0.0], [0.2 * 4 - 0.8 * 3, 1.0, 0.0]]
    )
    P = mdp.transition_matrix.toarray()
    np.testing.assert_allclose(P[0], [0.7, 0.3])  # (high, search)
    np.testing.assert_allclose(P[3], [0.8, 0.2])  # (low, search)
    np.testing.assert_allclose(P[2], [0.0, 0.0])  # (high, recharge) unavailable: empty row
    np.testing.assert_allclose(mdp.transitions("recharge").toarray(), [[0, 0], [1, 0]])


def test_several_rewards_per_next_state_and_duplicates_summed():
    mdp = pl.FiniteMDP.from_dynamics(
        {"s": {"a": [(0.25, "s", 1.0), (0.25, "s", 1.0), (0.5, "s", -1.0)]}}, gamma=0.5
    )
    assert sorted(mdp.outcomes("s", "a")) == [(0.5, "s", -1.0), (0.5, "s", 1.0)]
    assert mdp.p("s", 1.0, "s", "a") == pytest.approx(0.5)
    assert mdp.expected_reward[0, 0] == pytest.approx(0.0)
    assert mdp.transition_matrix.toarray()[0, 0] == pytest.approx(1.0)


def test_terminal_states_only_as_next_states():
    mdp = pl.FiniteMDP.from_dynamics({"a": {"go": [(1.0, "end", 1.0)]}}, terminal=["end"])
    assert mdp.states == ("a", "end")
    assert mdp.terminal.tolist() == [False, True]
    assert not mdp.action_mask[1].any()
    assert mdp.initial.tolist() == [1.0, 0.0]


def _robot_arrays():
    mdp = pl.problems.recycling_robot()
    P = mdp.transition_matrix.toarray().reshape(2, 3, 2).transpose(1, 0, 2)
    return mdp, P


def test_from_arrays_dense_and_sparse_round_trip():
    rng = np.random.default_rng(0)
    S, A = 6, 3
    P = rng.random((A, S, S)) * (rng.random((A, S, S)) < 0.5)
    P[:, np.arange(S), np.arange(S)] += 0.1
    P /= P.sum(axis=2, keepdims=True)
    R_sa = rng.normal(size=(S, A))
    R_ass = rng.normal(size=(A, S, S))
    for R in (R_sa, R_ass):
        dense = pl.FiniteMDP.from_arrays(P, R, gamma=0.9)
        sparse = pl.FiniteMDP.from_arrays([sp.csr_matrix(P[a]) for a in range(A)], R, gamma=0.9)
        for m in (dense, sparse):
            got = m.transition_matrix.toarray().reshape(S, A, S).transpose(1, 0, 2)
            np.testing.assert_allclose(got, P)
            expect = R if R.shape == (S, A) else np.einsum("ast,ast->sa", P, R)
            np.testing.assert_allclose(m.expected_reward, expect)
            assert m.states == tuple(range(S)) and m.actions == tuple(range(A))
    # sparse rewards at P's entries
    sparse_R = [sp.csr_matrix(R_ass[a] * (P[a] > 0)) for a in range(A)]
    m = pl.FiniteMDP.from_arrays([sp.csr_matrix(P[a]) for a in range(A)], sparse_R, gamma=0.9)
    np.testing.assert_allclose(m.expected_reward, np.einsum("ast,ast->sa", P, R_ass))


def test_from_arrays_terminal_rows_ignored():
    P = np.array([[[0.5, 0.5], [0.3, 0.3]]])  # row 1 is garbage but terminal
    mdp = pl.FiniteMDP.from_arrays(P, np.zeros((2, 1)), gamma=1.0, terminal=[1])
    assert mdp.terminal.tolist() == [False, True]
    assert mdp.n_outcomes == 2


def test_from_gymnasium_frozenlake_matches_env_statistics():
    env = gym.make("FrozenLake-v1")
    mdp = pl.FiniteMDP.from_gymnasium(env)
    assert mdp.n_states == 16 and mdp.n_actions == 4
    assert np.flatnonzero(mdp.terminal).tolist() == [5, 7, 11, 12, 15]
    assert mdp.initial[0] == 1.0
    # sampled transitions match the env's statistics
    rng = np.random.default_rng(1)
    base = env.unwrapped
    for s, a in [(0, 1), (6, 2), (14, 2)]:
        counts = np.zeros(16)
        n = 6000
        for _ in range(n):
            nxt, _, _ = mdp.step(s, a, rng)
            counts[nxt] += 1
        expect = np.zeros(16)
        for p, nxt, _, _ in base.P[s][a]:
            expect[nxt] += p
        np.testing.assert_allclose(counts / n, expect, atol=0.03)
    # env sampled against the model
    counts = np.zeros(16)
    for i in range(3000):
        env.reset(seed=i)
        nxt, *_ = env.step(1)
        counts[nxt] += 1
    np.testing.assert_allclose(counts / 3000, mdp.transition_matrix.toarray()[0 * 4 + 1], atol=0.03)
    # the goal transition pays 1
    assert mdp.expected_reward[14, 2] == pytest.approx(1 / 3)


def test_from_gymnasium_cliffwalking():
    mdp = pl.FiniteMDP.from_gymnasium("CliffWalking-v1")
    assert mdp.n_states == 48 and mdp.n_actions == 4
    assert np.flatnonzero(mdp.terminal).tolist() == [47]
    base = gym.make("CliffWalking-v1").unwrapped
    for s in (36, 24, 35):
        for a in range(4):
            exp = {}
            for p, nxt, r, _ in base.P[s][a]:
                exp[(nxt, r)] = exp.get((nxt, r), 0.0) + p
            got = {(n, r): p for p, n, r in mdp.outcomes(s, mdp.actions[a])}
            assert got == pytest.approx(exp)


def test_from_gymnasium_labels_toy_text_actions_as_gymnasium_documents_them():
    lake = pl.FiniteMDP.from_gymnasium("FrozenLake-v1")
    assert lake.actions == ("left", "down", "right", "up")
    # index order is the env's: action 2 (right) from the start cell of the
    # non-slippery lake moves to state 1
    flat = pl.FiniteMDP.from_gymnasium(gym.make("FrozenLake-v1", is_slippery=False))
    assert flat.outcomes(0, "right") == [(1.0, 1, 0.0)]
    assert flat.outcomes(0, "down") == [(1.0, 4, 0.0)]
    assert pl.FiniteMDP.from_gymnasium("CliffWalking-v1").actions == ("up", "right", "down", "left")
    assert pl.FiniteMDP.from_gymnasium("Taxi-v4").actions[4:] == ("pickup", "dropoff")


def test_from_gymnasium_taxi():
    mdp = pl.FiniteMDP.from_gymnasium("Taxi-v4")
    assert mdp.n_states == 500 and mdp.n_actions == 6
    assert mdp.terminal.sum() > 0


def test_step_is_seeded_and_matches_probabilities():
    mdp = pl.problems.recycling_robot()
    a = [mdp.step(0, 0, np.random.default_rng(7)) for _ in range(3)]
    b = [mdp.step(0, 0, np.random.default_rng(7)) for _ in range(3)]
    assert a == b
    rng = np.random.default_rng(0)
    n = 20000
    highs = sum(mdp.step(0, 0, rng)[0] == 0 for _ in range(n))
    assert highs / n == pytest.approx(0.7, abs=0.015)


def test_step_on_unavailable_action_is_clear():
    mdp = pl.problems.recycling_robot()
    with pytest.raises(pl.InvalidActionError, match="recharge.*not available.*high"):
        mdp.step(0, 2, np.random.default_rng(0))


def test_model_is_read_only():
    mdp = pl.problems.recycling_robot()
    with pytest.raises(ValueError):
        mdp.probs[0] = 1.0
    with pytest.raises(AttributeError):
        mdp.gamma = 0.5  # type: ignore[misc]


# ------------------------------------------------------------------ bad input, one test per case


def test_probabilities_not_summing_to_one():
    d = robot_dynamics()
    d["low"]["search"] = [(0.2, "low", 4.0), (0.73, "high", -3.0)]
    with pytest.raises(
        InvalidMDPError, match=r"p\(\. \| s='low', a='search'\) sums to 0\.93.*tolerance"
    ):
        pl.FiniteMDP.from_dynamics(d, gamma=0.9)


def test_negative_probability():
    with pytest.raises(InvalidMDPError, match=r"s='x', a='go'.*-0\.5.*>= 0"):
        pl.FiniteMDP.from_dynamics({"x": {"go": [(1.5, "x", 0.0), (-0.5, "x", 1.0)]}})


def test_non_finite_probability():
    with pytest.raises(InvalidMDPError, match="finite"):
        pl.FiniteMDP.from_dynamics({"x": {"go": [(float("nan"), "x", 0.0)]}})


def test_non_finite_reward():
    with pytest.raises(InvalidMDPError, match=r"reward inf.*s='x', a='go'.*not finite"):
        pl.FiniteMDP.from_dynamics({"x": {"go": [(1.0, "x", float("inf"))]}})


def test_unknown_next_state_label():
    with pytest.raises(UnknownLabelError, match="names next state 'nowhere'"):
        pl.FiniteMDP.from_dynamics({"x": {"go": [(1.0, "nowhere", 0.0)]}})


def test_non_terminal_state_without_actions():
    with pytest.raises(InvalidMDPError, match="non-terminal state 'y' has no available action"):
        pl.FiniteMDP.from_dynamics({"x": {"go": [(1.0, "y", 0.0)]}, "y": {}})


def test_terminal_state_with_outgoing_dynamics():
    with pytest.raises(InvalidMDPError, match="terminal state 'y' is given outgoing dynamics"):
        pl.FiniteMDP.from_dynamics(
            {"x": {"go": [(1.0, "y", 0.0)]}, "y": {"go": [(1.0, "x", 0.0)]}}, terminal=["y"]
        )


@pytest.mark.parametrize("gamma", [-0.1, 1.5, float("nan"), "high"])
def test_gamma_outside_unit_interval(gamma):
    # One check of gamma for every entry point: the same error type and words.
    with pytest.raises(InvalidArgumentError, match="gamma must be"):
        pl.FiniteMDP.from_dynamics(robot_dynamics(), gamma=gamma)
    with pytest.raises(InvalidArgumentError, match="gamma must be"):
        pl.problems.recycling_robot().with_gamma(gamma)


def test_from_arrays_shape_mismatch_P_not_square():
    with pytest.raises(ShapeError, match=r"\(2, 3, 4\)|shape"):
        pl.FiniteMDP.from_arrays(np.ones((2, 3, 4)) / 4, np.zeros((3, 2)))


def test_from_arrays_shape_mismatch_P_ndim():
    with pytest.raises(ShapeError, match=r"got shape \(3, 3\)"):
        pl.FiniteMDP.from_arrays(np.eye(3), np.zeros((3, 1)))


def test_from_arrays_shape_mismatch_list_of_matrices():
    with pytest.raises(ShapeError, match=r"P\[1\] has shape \(2, 2\).*\(3, 3\)"):
        pl.FiniteMDP.from_arrays([sp.eye(3), sp.eye(2)], np.zeros((3, 2)))


def test_from_arrays_shape_mismatch_R():
    with pytest.raises(ShapeError, match=r"R has shape \(2, 3\); expected \(S, A\) = \(3, 2\)"):
        pl.FiniteMDP.from_arrays(np.stack([np.eye(3)] * 2), np.zeros((2, 3)))


def test_from_arrays_shape_mismatch_R_list():
    with pytest.raises(ShapeError, match="R as a list must hold A = 2 matrices"):
        pl.FiniteMDP.from_arrays(np.stack([np.eye(3)] * 2), [np.zeros((3, 3))])


def test_from_arrays_shape_mismatch_terminal_and_mask():
    P = np.stack([np.eye(3)] * 2)
    with pytest.raises(ShapeError, match=r"terminal mask has shape \(2,\)"):
        pl.FiniteMDP.from_arrays(P, np.zeros((3, 2)), terminal=np.array([True, False]))
    with pytest.raises(ShapeError, match=r"action_mask has shape \(3, 3\)"):
        pl.FiniteMDP.from_arrays(P, np.zeros((3, 2)), action_mask=np.ones((3, 3), bool))


def test_from_arrays_row_not_summing_to_one():
    P = np.stack([np.eye(3)] * 2)
    P[1, 2] = [0.5, 0.2, 0.2]
    with pytest.raises(InvalidMDPError, match=r"p\(\. \| s=2, a=1\) sums to 0\.9"):
        pl.FiniteMDP.from_arrays(P, np.zeros((3, 2)))


def test_env_without_P():
    with pytest.raises(InvalidMDPError, match="'CartPole-v1' has no transition model `P`"):
        pl.FiniteMDP.from_gymnasium(gym.make("CartPole-v1"))


def test_labels_must_be_unique_and_hashable():
    with pytest.raises(InvalidMDPError, match="appears twice"):
        pl.FiniteMDP.from_arrays(np.stack([np.eye(2)]), np.zeros((2, 1)), states=["a", "a"])


def test_unknown_label_lookup():
    mdp = pl.problems.recycling_robot()
    with pytest.raises(UnknownLabelError, match="unknown state 'medium'.*'high', 'low'"):
        mdp.state_index("medium")
    with pytest.raises(UnknownLabelError, match="unknown action 'fly'"):
        mdp.action_index("fly")


def test_grid_wind_needs_one_value_per_column():
    with pytest.raises(InvalidMDPError, match="one upward push per column: 3 columns, 2 values"):
        pl.grid_mdp(
            ["S.G"], {"S": "start", ".": "grass", "G": "goal"}, lambda *_: -1.0, wind=[0, 1]
        )
    mdp = pl.grid_mdp(
        ["...", "S.G"], {"S": "start", ".": "grass", "G": "goal"}, lambda *_: -1.0, wind=[0, 1, 0]
    )
    assert mdp.grid is not None and mdp.grid.wind == (0, 1, 0)
    # the wind of the column the move starts in: right from (1, 1) lands one row up
    out = mdp.outcomes((1, 1), "right")
    assert [o[1] for o in out] == [(0, 2)]


def _two_state_arrays():
    P = np.array([[[0.5, 0.5], [0.0, 1.0]], [[1.0, 0.0], [0.2, 0.8]]])
    R = np.array([[1.0, 0.0], [0.0, 2.0]])
    return P, R


def test_from_arrays_takes_an_object_array_of_sparse_matrices():
    # pymdptoolbox's convention: P is a NumPy object array holding A sparse matrices.
    P, R = _two_state_arrays()
    obj = np.empty(2, dtype=object)
    obj[0], obj[1] = sp.csr_matrix(P[0]), sp.csr_matrix(P[1])
    a = pl.FiniteMDP.from_arrays(obj, R, gamma=0.9)
    b = pl.FiniteMDP.from_arrays(P, R, gamma=0.9)
    np.testing.assert_array_equal(a.transition_matrix.toarray(), b.transition_matrix.toarray())
    np.testing.assert_array_equal(a.expected_reward, b.expected_reward)
    # rewards as an object array of sparse (A, S, S) matrices too
    robj = np.empty(2, dtype=object)
    robj[0], robj[1] = sp.csr_matrix(np.full((2, 2), 3.0)), sp.csr_matrix(np.full((2, 2), -1.0))
    c = pl.FiniteMDP.from_arrays(obj, robj, gamma=0.9)
    np.testing.assert_allclose(c.expected_reward, [[3.0, -1.0], [3.0, -1.0]])


def test_from_arrays_accepts_float32_stochastic_to_float32_precision():
    # rows of ten float32 tenths sum to 1 + 1.5e-8 in float64: stochastic in float32
    P = np.full((2, 10, 10), 0.1, dtype=np.float32)
    assert abs(P.astype(np.float64).sum(axis=2)[0, 0] - 1.0) > pl.mdp.PROB_TOL
    mdp = pl.FiniteMDP.from_arrays(P, np.zeros((10, 2)), gamma=0.9)
    sums = mdp.transition_matrix.sum(axis=1)
    np.testing.assert_allclose(sums, 1.0, rtol=0, atol=1e-15)  # normalised
    # float64 keeps its tight tolerance; the message shows the deviation
    P64 = np.full((1, 2, 2), 0.5)
    P64[0, 0, 0] += 3e-8
    with pytest.raises(InvalidMDPError) as err:
        pl.FiniteMDP.from_arrays(P64, np.zeros((2, 1)))
    msg = str(err.value)
    assert "sums to 1.00000003 (off by +3e-08)" in msg and "tolerance 1e-08" in msg
    # float32 off by more than its precision is refused, with enough digits
    P32 = np.full((1, 2, 2), 0.5, dtype=np.float32)
    P32[0, 1, 1] = 0.501
    with pytest.raises(InvalidMDPError, match=r"s=1, a=0\) sums to 1\.001 \(off by \+0\.001\)"):
        pl.FiniteMDP.from_arrays(P32, np.zeros((2, 1)))


def test_messages_show_numbers_without_numpy_reprs():
    P, R = _two_state_arrays()
    P[1, 0, 0] = -0.5
    with pytest.raises(InvalidMDPError) as err:
        pl.FiniteMDP.from_arrays(P, R)
    assert "probability -0.5;" in str(err.value) and "np.float64" not in str(err.value)
    d = robot_dynamics()
    d["low"]["search"] = [(0.2, "low", 4.0), (0.73, "high", -3.0)]
    with pytest.raises(InvalidMDPError, match=r"sums to 0\.93 \(off by -0\.07\)"):
        pl.FiniteMDP.from_dynamics(d)


@pytest.mark.parametrize(
    ("P", "R", "kwargs", "words"),
    [
        (
            np.array([[["a", "b"], ["c", "d"]]]),
            np.zeros((2, 1)),
            {},
            "P must be an array of real numbers",
        ),
        ([[[1.0, 0.0], [0.0, 1.0]]], [["x"], ["y"]], {}, "R must be an array of real numbers"),
        ([[[1.0, 0.0], [0.0]]], np.zeros((2, 1)), {}, "rows of different lengths"),
        ([[[1.0, 0.0], [0.0, 1.0]]], np.zeros((2, 1)), {"terminal": ["s1"]}, "terminal must"),
        ([[[1.0, 0.0], [0.0, 1.0]]], np.zeros((2, 1)), {"initial": ["a", "b"]}, "initial must"),
        ([[[1.0, 0.0], [0.0, 1.0]]], np.zeros((2, 1)), {"gamma": "0.9"}, "gamma must be"),
    ],
)
def test_from_arrays_bad_input_is_a_policylab_error(P, R, kwargs, words):
    with pytest.raises(pl.exceptions.PolicylabError, match=words):
        pl.FiniteMDP.from_arrays(P, R, **kwargs)


def test_low_level_step_and_sample_check_indices_and_generator():
    robot = pl.problems.recycling_robot()
    rng = np.random.default_rng(0)
    with pytest.raises(pl.exceptions.InvalidActionError, match=r"state index in \[0, 2\)"):
        robot.step(99, 0, rng)
    with pytest.raises(InvalidArgumentError, match="numpy.random.Generator"):
        robot.step(0, 0, 3)
    pi = pl.Policy.uniform(robot)
    with pytest.raises(pl.exceptions.InvalidPolicyError, match="non-terminal state"):
        pi.sample(99, rng)
    with pytest.raises(pl.exceptions.InvalidPolicyError, match="numpy.random.Generator"):
        pi.sample(0, 5)


@pytest.mark.parametrize(
    ("rows", "reward", "kwargs", "words"),
    [
        ("S.G", lambda a, b, k: 0.0, {}, "a list of strings, one per row"),
        ([1, 2], lambda a, b, k: 0.0, {}, "a list of strings"),
        (["S.G"], 5, {}, "reward must be a function"),
        (["S.G"], lambda a, b, k: "x", {}, "returned 'x'; it must return a number"),
        (["S.G"], lambda a, b, k: 0.0, {"wind": ["a", "b", "c"]}, "wind must hold integers"),
        (["S.G"], lambda a, b, k: 0.0, {"gamma": 3}, "gamma must be in [0, 1]"),
    ],
)
def test_grid_mdp_bad_input_is_a_policylab_error(rows, reward, kwargs, words):
    from policylab.mdp.grid import grid_mdp

    legend = {"S": "start", ".": "grass", "G": "goal"}
    with pytest.raises(pl.exceptions.PolicylabError) as err:
        grid_mdp(rows, legend, reward, **kwargs)
    assert words in str(err.value)


def test_outcomes_with_numpy_numbers_are_written_plainly():
    with pytest.raises(InvalidMDPError) as err:
        pl.FiniteMDP.from_dynamics({"a": {"x": [(np.float64(0.5), "a")]}})
    assert "outcome (0.5, 'a') of" in str(err.value) and "np.float64" not in str(err.value)
