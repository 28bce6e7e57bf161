"""The notes' problems: numbers as in the notes and Sutton & Barto."""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl


def linear_solve_v(mdp, pi):
    S, A = mdp.n_states, mdp.n_actions
    P = mdp.transition_matrix.toarray().reshape(S, A, S)
    Ppi = np.einsum("sa,sat->st", pi.probs, P)
    r = (pi.probs * mdp.expected_reward).sum(1)
    live = ~mdp.terminal
    v = np.zeros(S)
    v[live] = np.linalg.solve(np.eye(live.sum()) - mdp.gamma * Ppi[np.ix_(live, live)], r[live])
    return v


def test_recycling_robot_defaults_are_the_notes_numbers():
    m = pl.problems.recycling_robot()
    assert m.p("high", 4.0, "high", "search") == pytest.approx(0.7)
    assert m.p("low", 4.0, "high", "search") == pytest.approx(0.3)
    assert m.p("low", 4.0, "low", "search") == pytest.approx(0.2)
    assert m.p("high", -3.0, "low", "search") == pytest.approx(0.8)
    assert m.p("high", 1.0, "high", "wait") == 1.0
    assert m.p("high", 0.0, "low", "recharge") == 1.0
    assert m.available_actions("high") == ["search", "wait"]
    m2 = pl.problems.recycling_robot(alpha=0.5, beta=0.5, r_search=2, r_wait=0.5, r_rescue=-10)
    assert m2.p("high", -10.0, "low", "search") == pytest.approx(0.5)


def test_mountain_gridworld_bad_policy_values():
    m = pl.problems.mountain_gridworld()
    v = linear_solve_v(m, pl.problems.mountain_gridworld_bad_policy(m))
    assert v[m.state_index((2, 0))] == pytest.approx(-6.0)
    assert v[m.state_index((2, 1))] == pytest.approx(-5.0)
    assert v[m.state_index((2, 2))] == 0.0
    best = pl.Policy.deterministic(
        m, {s: "right" if s[0] == 2 else "down" for s in m.states if s != (2, 2)}
    )
    assert linear_solve_v(m, best)[m.state_index((2, 0))] == pytest.approx(4.0)


def test_slippery_gridworld_dynamics():
    m = pl.problems.slippery_gridworld()
    assert m.states == (1, 4, 2, 3)
    assert m.terminal.tolist() == [False, True, False, False]
    # from 1, "right" hits the wall: stays with 0.7 + 0.1 (up) = 0.9 ... down slips to 2
    assert m.p(1, -1.0, 1, "right") == pytest.approx(0.9)
    assert m.p(2, -1.0, 1, "right") == pytest.approx(0.1)
    assert m.p(4, 10.0, 3, "up") == pytest.approx(0.7)
    assert m.p(4, 10.0, 3, "left") == pytest.approx(0.1)
    # never through the wall
    for a in m.actions:
        assert m.p(4, 10.0, 1, a) == 0.0
    assert m.initial.tolist() == [1.0, 0.0, 0.0, 0.0]


def test_registry_and_unknown_problem():
    names = [p.name for p in pl.problems.list_problems()]
    assert {"recycling-robot", "mountain-gridworld", "slippery-gridworld"} <= set(names)
    with pytest.raises(pl.UnknownProblemError, match="unknown problem 'nope'.*recycling-robot"):
        pl.problems.get_problem("nope")


def test_public_problem_lookup_by_any_spelling():
    from policylab.exceptions import UnknownProblemError
    from policylab.problems.registry import find_problem, problem, problem_names

    assert find_problem("Recycling_Robot ").name == "recycling-robot"
    assert find_problem("no-such") is None
    assert "recycling-robot" in problem_names() and problem_names() == sorted(problem_names())
    with pytest.raises(UnknownProblemError, match=r"did you mean 'recycling-robot'\?"):
        problem("recycling-robt")
