"""UCT, players and the arena."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError
from policylab.games import (
    CONNECT_FOUR,
    TIC_TAC_TOE,
    UCT,
    arena,
    make_player,
    solve_tic_tac_toe,
    wilson_interval,
)
from policylab.games.mcts import rollout_outcome


def test_uct_finds_wins_and_blocks():
    # X to move wins at once in column 1 (three stacked)
    assert UCT(300, seed=0).choose(CONNECT_FOUR.from_moves("121212")) == 0
    # O to move must block column 1
    assert UCT(1000, seed=0).choose(CONNECT_FOUR.from_moves("12121")) == 0
    # tic-tac-toe: X (1, 2 vs O 5, 7) wins at 3
    assert UCT(500, seed=1).choose(TIC_TAC_TOE.from_moves("1527")) == 2


def test_uct_same_seed_same_counts_and_visits_add_up():
    s = CONNECT_FOUR.from_moves("44")
    a = UCT(200, seed=3).visit_counts(s)
    assert np.array_equal(a, UCT(200, seed=3).visit_counts(s)) and a.sum() == 200


def test_uct_plays_tictactoe_near_perfectly():
    """With 2000 simulations UCT picks an optimal move in most positions it can meet."""
    sol = solve_tic_tac_toe()
    uct = UCT(2000, seed=0)
    rng = np.random.default_rng(0)
    ok = total = 0
    for _ in range(30):
        s = TIC_TAC_TOE.initial()
        for _ in range(int(rng.integers(0, 6))):
            if s.is_terminal():
                break
            s = s.play(int(rng.choice(s.legal_actions())))
        if s.is_terminal():
            continue
        total += 1
        ok += uct.choose(s) in sol.best_moves(s)
    assert ok >= 0.9 * total


def test_rollout_outcome_is_an_outcome():
    rng = np.random.default_rng(0)
    vals = {rollout_outcome(CONNECT_FOUR.initial(), rng) for _ in range(200)}
    assert vals <= {-1.0, 0.0, 1.0} and {-1.0, 1.0} <= vals
    assert rollout_outcome(CONNECT_FOUR.from_moves("1212121"), rng) == -1.0  # O to move, lost


def test_arena_alternates_colours_and_counts():
    g = TIC_TAC_TOE
    res = arena(g, make_player("perfect", g, 0), make_player("perfect", g, 1), 10)
    assert (res.wins, res.draws, res.losses, res.games) == (0, 10, 0, 10)
    res = arena(g, make_player("perfect", g, 0), make_player("random", g, 1), 40)
    assert res.losses == 0 and res.wins > 20
    assert res.to_json() == {"wins": res.wins, "draws": res.draws, "losses": 0, "games": 40}
    # random against perfect: mirror image
    res2 = arena(g, make_player("random", g, 1), make_player("perfect", g, 0), 40)
    assert res2.wins == 0


def test_wilson_interval_known_values():
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-4)
    lo, hi = wilson_interval(5, 10)
    assert (lo, hi) == (pytest.approx(0.2366, abs=1e-4), pytest.approx(0.7634, abs=1e-4))
    assert wilson_interval(0, 0) == (0.0, 1.0)  # no games: nothing known
    with pytest.raises(InvalidArgumentError, match="0 <= k <= n"):
        wilson_interval(11, 10)
    with pytest.raises(InvalidArgumentError, match="0 <= k <= n"):
        wilson_interval(1, -1)


def test_player_spec_errors(tmp_path):
    with pytest.raises(InvalidArgumentError, match="unknown player 'alphago'"):
        make_player("alphago", TIC_TAC_TOE)
    with pytest.raises(InvalidArgumentError, match="positive number of simulations"):
        make_player("mcts:0", TIC_TAC_TOE)
    with pytest.raises(InvalidArgumentError, match="positive number of simulations"):
        make_player("mcts:ten", TIC_TAC_TOE)
    with pytest.raises(InvalidArgumentError, match="finished game"):
        UCT(10).choose(TIC_TAC_TOE.from_moves("14253"))
    with pytest.raises(InvalidArgumentError, match="--games"):
        arena(
            TIC_TAC_TOE, make_player("random", TIC_TAC_TOE), make_player("random", TIC_TAC_TOE), 0
        )
    from policylab.exceptions import CheckpointError

    with pytest.raises(CheckpointError, match="not a game learner's run folder"):
        make_player(str(tmp_path), TIC_TAC_TOE)


def _sensible(stones, rng):
    """A Connect Four position after sensible random play (no move wins at once), or None."""
    s = CONNECT_FOUR.initial()
    while len(s.moves) < stones:
        safe = [
            a
            for a in s.legal_actions()
            if s.play(a).winner is None
            and not any(s.play(a).play(b).winner is not None for b in s.play(a).legal_actions())
        ]
        if not safe:
            return None
        s = s.play(int(rng.choice(safe)))
    return s


def test_compiled_playout_is_exact_when_one_move_is_left():
    rng = np.random.default_rng(5)
    checked = 0
    while checked < 20:
        s = CONNECT_FOUR.initial()
        while not s.is_terminal() and len(s.moves) < 41:
            s = s.play(int(rng.choice(s.legal_actions())))
        if s.is_terminal():
            continue
        (last,) = s.legal_actions()
        assert rollout_outcome(s, rng) == s.play(last).outcome(s.player)
        checked += 1


def test_compiled_uct_counts_add_up_and_skip_full_columns():
    s = CONNECT_FOUR.from_moves("111111444")  # column 1 full
    counts = UCT(700, seed=2).visit_counts(s)
    assert counts[0] == 0 and counts.sum() == 700 and (counts[1:] > 0).all()
    assert counts.dtype == np.int64 and counts.shape == (7,)


def test_compiled_uct_mostly_plays_solver_optimal_moves_late_in_the_game():
    """In positions with 28 to 34 stones UCT with 3000 playouts rarely misses the best move."""
    from policylab.games import connect_four_solver

    solver = connect_four_solver()
    rng = np.random.default_rng(11)
    uct = UCT(3000, seed=0)
    ok = total = 0
    while total < 25:
        s = _sensible(int(rng.integers(28, 35)), rng)
        if s is None or s.is_terminal():
            continue
        total += 1
        ok += uct.choose(s) in solver.best_moves(s)
    assert ok >= 0.8 * total


def test_worst_outcome_equals_the_plain_minimax_over_every_line():
    from policylab.games.arena import worst_outcome

    class FirstMove:  # deterministic, and loses a lot: the minimum is not always 0
        name = "first"

        def choose(self, state):
            return state.legal_actions()[0]

    def plain(player, s, me):
        if s.is_terminal():
            return s.outcome(me)
        if s.player == me:
            return plain(player, s.play(player.choose(s)), me)
        return min(plain(player, s.play(a), me) for a in s.legal_actions())

    for moves in ("", "5", "15", "1529"):
        s = TIC_TAC_TOE.from_moves(moves)
        for me in (0, 1):
            want = plain(FirstMove(), s, me)
            assert worst_outcome(FirstMove(), s, me, lambda t: t.legal_actions()) == want
    assert worst_outcome(FirstMove(), TIC_TAC_TOE.initial(), 0, lambda t: t.legal_actions()) == -1
