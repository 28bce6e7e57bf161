"""Exact solvers: the full tic-tac-toe table and the Connect Four negamax."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError
from policylab.games import CONNECT_FOUR, TIC_TAC_TOE, ConnectFourSolver, solve_tic_tac_toe


def test_tictactoe_reachable_positions_and_value():
    sol = solve_tic_tac_toe()
    assert sol.n_positions == 5478
    assert sol.value(TIC_TAC_TOE.initial()) == 0
    assert sol.best_moves(TIC_TAC_TOE.initial()) == tuple(range(9))  # every opening draws


def test_tictactoe_known_positions():
    sol = solve_tic_tac_toe()
    # after a corner, only the centre holds the draw for O
    assert sol.best_moves(TIC_TAC_TOE.from_moves("1")) == (4,)
    s = TIC_TAC_TOE.from_moves("152")  # X 1, 2 and O 5: O must block at 3
    assert sol.best_moves(s) == (2,) and sol.value(s) == 0
    assert sol.value(TIC_TAC_TOE.from_moves("1527")) == 1  # X 1, 2 and O 5, 7: X wins at 3
    assert 2 in sol.best_moves(TIC_TAC_TOE.from_moves("1527"))
    assert sol.value(TIC_TAC_TOE.from_moves("14253")) == -1  # finished: O to move has lost


def test_tictactoe_table_agrees_with_plain_minimax():
    """Every table entry equals an independent minimax from X's view (no memo)."""
    sol = solve_tic_tac_toe()
    cache = {}

    def minimax_x(s):  # value for X
        if s.key in cache:
            return cache[s.key]
        if s.is_terminal():
            v = s.outcome(0)
        else:
            vals = [minimax_x(s.play(a)) for a in s.legal_actions()]
            v = max(vals) if s.player == 0 else min(vals)
        cache[s.key] = v
        return v

    def walk(s, seen):
        if s.key in seen:
            return
        seen.add(s.key)
        v = minimax_x(s)
        assert sol.values[s.key] == (v if s.player == 0 else -v)
        for a in s.legal_actions():
            walk(s.play(a), seen)

    seen = set()
    walk(TIC_TAC_TOE.initial(), seen)
    assert len(seen) == 5478


def brute_force_score(s, memo):
    """Pons' score by plain negamax over the whole remaining game (no pruning)."""
    if s.key in memo:
        return memo[s.key]
    best = -100
    for a in s.legal_actions():
        c = s.play(a)
        if c.winner is not None:
            sc = 22 - (len(c.moves) + 1) // 2  # a win with the mover's k-th stone
        elif c.is_full():
            sc = 0
        else:
            sc = -brute_force_score(c, memo)
        best = max(best, sc)
    memo[s.key] = best
    return best


@pytest.fixture(scope="module")
def solver():
    return ConnectFourSolver(table_size=(1 << 20) + 7)


def test_connect_four_matches_brute_force_near_the_end(solver):
    rng = np.random.default_rng(1)
    checked = 0
    scores = set()
    while checked < 25:
        s = CONNECT_FOUR.initial()
        target = int(rng.integers(30, 37))
        while len(s.moves) < target and not s.is_terminal():
            s = s.play(int(rng.choice(s.legal_actions())))
        if s.is_terminal():
            continue
        expected = brute_force_score(s, {})
        assert solver.score(s) == expected, s.position_string()
        mv = solver.move_scores(s)
        for a, v in mv.items():
            c = s.play(a)
            if c.winner is not None:
                assert v == 22 - (len(c.moves) + 1) // 2
            elif c.is_full():
                assert v == 0
            else:
                assert v == -brute_force_score(c, {})
        checked += 1
        scores.add(expected)
    assert len(scores) >= 4  # wins, losses and draws of several lengths were checked


def _wins_within(s, k):
    """Can the player to move force a win with at most k more of their own stones?"""
    for a in s.legal_actions():
        c = s.play(a)
        if c.winner is not None:
            return True
        if k == 1 or c.is_full():
            continue
        replies = [c.play(b) for b in c.legal_actions()]
        if all(d.winner is None and not d.is_full() and _wins_within(d, k - 1) for d in replies):
            return True
    return False


def test_4455_scores_18_by_a_bounded_brute_force(solver):
    """'4455': X has 2 stones, so no win is possible with the 3rd (score 19), and a
    forced win with the 4th exists (score 18), found here by exhaustive search."""
    s = CONNECT_FOUR.from_moves("4455")
    assert not _wins_within(s, 1)  # no win with the 3rd stone: score < 19
    assert _wins_within(s, 2)  # a forced win with the 4th stone: score = 22 - 4
    assert solver.score(s) == 18
    # columns 3 and 6 make an open three: O, to move, then loses to X's 4th stone
    assert solver.score(s.play(2)) == solver.score(s.play(5)) == -18


def test_connect_four_known_scores(solver):
    # immediate win: X to move with three stacked in column 1 wins with the 4th stone
    assert solver.score(CONNECT_FOUR.from_moves("121212")) == 22 - 4
    # and O, to move after X's blunder, loses: X's 4th stone wins whatever O does
    assert solver.score(CONNECT_FOUR.from_moves("44553")) == -(22 - 4)


def test_connect_four_solver_errors(solver):
    with pytest.raises(InvalidArgumentError, match="is over"):
        solver.score(CONNECT_FOUR.from_moves("1212121"))
    with pytest.raises(InvalidArgumentError, match="Connect Four position"):
        solver.score(TIC_TAC_TOE.initial())
    with pytest.raises(InvalidArgumentError, match="table_size"):
        ConnectFourSolver(table_size=-1)
