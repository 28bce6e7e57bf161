"""Game rules: wins on every line, draws, illegal moves, malformed positions."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from policylab.exceptions import InvalidActionError, InvalidArgumentError, UnknownProblemError
from policylab.games import CONNECT_FOUR, TIC_TAC_TOE, get_game, is_game
from policylab.games.connect_four import has_four
from policylab.games.tictactoe import LINES


def test_registry_names():
    assert get_game("tic_tac_toe") is TIC_TAC_TOE and get_game("Connect4") is CONNECT_FOUR
    assert is_game("connect-four") and not is_game("gridworld-4x4")
    with pytest.raises(UnknownProblemError, match="known games: tic-tac-toe, connect-four"):
        get_game("chess")


@pytest.mark.parametrize("line", LINES)
@pytest.mark.parametrize("player", [0, 1])
def test_tictactoe_every_line_wins(line, player):
    cells = [c for c in range(9) if line >> c & 1]
    others = [c for c in range(9) if not line >> c & 1]
    # the winner plays its line; the other plays cells off the line that make no line
    for filler in itertools.permutations(others, 3):
        fill = set(filler)
        if any(m & sum(1 << c for c in fill) == m for m in LINES):
            continue
        seq = []
        for i in range(3):
            pair = (cells[i], filler[i]) if player == 0 else (filler[i], cells[i])
            seq += pair
        if player == 0:
            seq = seq[:5]
        s = TIC_TAC_TOE.initial()
        for a in seq:
            s = s.play(a)
        assert s.winner == player and s.is_terminal()
        assert s.outcome(player) == 1.0 and s.outcome(1 - player) == -1.0
        assert s.legal_actions() == ()
        break


def test_tictactoe_draw_and_outcome():
    s = TIC_TAC_TOE.from_moves("123546879")  # X O X / X O O / O X X: full, no line
    assert s.is_full() and s.winner is None and s.outcome(0) == 0.0 == s.outcome(1)
    assert str(s).splitlines() == ["X O X", "X O O", "O X X"]
    with pytest.raises(InvalidArgumentError, match="not over"):
        TIC_TAC_TOE.from_moves("15").outcome(0)


def test_tictactoe_illegal_moves():
    s = TIC_TAC_TOE.from_moves("5")
    with pytest.raises(InvalidActionError, match=r"move 5 is not legal in position '5'"):
        s.play(4)
    with pytest.raises(InvalidActionError, match="not legal"):
        s.play(9)
    won = TIC_TAC_TOE.from_moves("14253")
    with pytest.raises(InvalidActionError, match="after the end of the game"):
        won.play(8)
    with pytest.raises(InvalidActionError, match="goes on after the end"):
        TIC_TAC_TOE.from_moves("142536")
    with pytest.raises(InvalidActionError, match="illegal move 2"):
        TIC_TAC_TOE.from_moves("11")
    with pytest.raises(InvalidArgumentError, match="character 2 is '0'"):
        TIC_TAC_TOE.from_moves("10")
    with pytest.raises(InvalidArgumentError, match="string of moves"):
        TIC_TAC_TOE.from_moves(15)


def _c4_line_cells():
    """Every four-cell line of the 6x7 board as (row, col) lists: 69 of them."""
    lines = []
    for r in range(6):
        for c in range(7):
            for dr, dc in ((0, 1), (1, 0), (1, 1), (-1, 1)):
                cells = [(r + k * dr, c + k * dc) for k in range(4)]
                if all(0 <= rr < 6 and 0 <= cc < 7 for rr, cc in cells):
                    lines.append(cells)
    return lines


def test_connect_four_has_four_on_all_69_lines_and_no_wrap():
    lines = _c4_line_cells()
    assert len(lines) == 69
    for cells in lines:
        bits = sum(1 << (c * 7 + r) for r, c in cells)
        assert has_four(bits)
        for drop in cells:  # three of the four are not a win
            assert not has_four(bits & ~(1 << (drop[1] * 7 + drop[0])))
    # a "line" wrapping from the top of one column to the bottom of the next is no win
    assert not has_four(sum(1 << (c * 7 + r) for c, r in ((0, 4), (0, 5), (1, 0), (1, 1))))


def test_connect_four_wins_by_play_against_oracle():
    """Random games: the game ends exactly when a line of the 69 is complete."""
    rng = np.random.default_rng(0)
    lines = _c4_line_cells()
    for _ in range(200):
        s = CONNECT_FOUR.initial()
        while not s.is_terminal():
            s = s.play(int(rng.choice(s.legal_actions())))
            board = {(r, c): s.stone(r, c) for r in range(6) for c in range(7)}
            owners = [
                {board[rc] for rc in cells}
                for cells in lines
                if len({board[rc] for rc in cells}) == 1 and board[cells[0]] is not None
            ]
            expected = None if not owners else next(iter(owners[0]))
            assert s.winner == expected
        assert s.winner is not None or s.is_full()


def test_connect_four_rules_and_errors():
    s = CONNECT_FOUR.from_moves("4455")
    assert s.player == 0 and s.legal_actions() == tuple(range(7))
    assert s.stone(0, 3) == 0 and s.stone(1, 3) == 1 and s.stone(0, 4) == 0
    assert s.encode().shape == (2, 6, 7) and s.encode()[0, 5, 3] == 1.0  # X (to move) bottom
    assert s.position_string() == "4455"
    assert CONNECT_FOUR.from_moves("1212121").winner == 0  # four in column 1
    full = CONNECT_FOUR.from_moves("111111")
    assert 0 not in full.legal_actions()
    with pytest.raises(InvalidActionError, match=r"move 1 is not legal.*legal moves are 2, 3"):
        full.play(0)
    with pytest.raises(InvalidActionError, match="illegal move 7"):
        CONNECT_FOUR.from_moves("1111111")
    with pytest.raises(InvalidActionError, match="after the end"):
        CONNECT_FOUR.from_moves("1212121").play(3)
    with pytest.raises(InvalidArgumentError, match="character 3 is '8'"):
        CONNECT_FOUR.from_moves("448")
    assert CONNECT_FOUR.from_moves(" 44 ".strip()).key == CONNECT_FOUR.from_moves("44").key
    # a transposition reaches the same key
    assert CONNECT_FOUR.from_moves("1234").key == CONNECT_FOUR.from_moves("3214").key


def test_connect_four_draw():
    """A game that fills the board with no four in a line (checked on the 69 lines) is a draw."""
    s = CONNECT_FOUR.from_moves("452132145671363423737227774246535165114566")
    board = {(r, c): s.stone(r, c) for r in range(6) for c in range(7)}
    assert all(len({board[rc] for rc in cells}) > 1 for cells in _c4_line_cells())
    assert s.is_full() and s.winner is None and s.outcome(0) == 0.0 and s.legal_actions() == ()
