"""Sutton & Barto's self-play TD learner: with its defaults it never loses, exhaustively."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError, RunFolderError
from policylab.games import TIC_TAC_TOE, make_player, solve_tic_tac_toe
from policylab.games.arena import worst_outcome
from policylab.games.learned import train_selfplay_td
from policylab.games.selfplay_td import SelfPlayTDConfig, position_code


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    run = tmp_path_factory.mktemp("td") / "run"
    player = train_selfplay_td(run)  # the defaults
    return run, player


@pytest.mark.parametrize("me", [0, 1])
def test_never_loses_to_perfect_play_first_or_second(trained, me):
    _, player = trained
    sol = solve_tic_tac_toe()
    # every line of the perfect player (each of its optimal moves): always a draw
    assert worst_outcome(player, TIC_TAC_TOE.initial(), me, sol.best_moves) == 0.0
    # and it never loses against any opponent at all (every legal move of the other side)
    assert worst_outcome(player, TIC_TAC_TOE.initial(), me, lambda s: s.legal_actions()) >= 0.0


def test_run_folder_player_and_refusals(trained):
    run, player = trained
    loaded = make_player(str(run), TIC_TAC_TOE)
    s = TIC_TAC_TOE.from_moves("15")
    assert loaded.choose(s) == player.choose(s)
    with pytest.raises(RunFolderError, match="already holds a run"):
        train_selfplay_td(run)
    with pytest.raises(InvalidArgumentError, match="learned tic-tac-toe, not connect-four"):
        from policylab.games import CONNECT_FOUR

        make_player(str(run), CONNECT_FOUR)


def test_same_seed_same_table_and_resume_matches(tmp_path):
    cfg = SelfPlayTDConfig(episodes=4000, chunks=4, seed=7)
    a = train_selfplay_td(tmp_path / "a", cfg).values
    b = train_selfplay_td(tmp_path / "b", cfg).values
    assert np.array_equal(a, b)
    # stop after two chunks (as a crash would), then resume: the same table as one go
    from policylab.deep.common.checkpoint import load_checkpoint, save_checkpoint

    meta, tensors = load_checkpoint(tmp_path / "a" / "checkpoint.pt")
    part = train_selfplay_td(tmp_path / "c", SelfPlayTDConfig(episodes=4000, chunks=4, seed=7))
    # rebuild chunk-2 state by training a fresh 2-chunk prefix
    from policylab.games.selfplay_td import initial_values, train_chunk

    V = initial_values()
    for c in range(2):
        train_chunk(V, cfg, c)
    meta2 = {**meta, "chunks_done": 2, "episodes_done": 2000}
    save_checkpoint(tmp_path / "c" / "checkpoint.pt", meta2, {"values": V})
    resumed = train_selfplay_td(tmp_path / "c", resume=True).values
    assert np.array_equal(resumed, a) and np.array_equal(part.values, a)
    with pytest.raises(RunFolderError, match="holds no run to resume"):
        train_selfplay_td(tmp_path / "d", resume=True)


def test_config_checks_and_codes():
    with pytest.raises(InvalidArgumentError, match="alpha"):
        SelfPlayTDConfig(alpha=0).validate()
    with pytest.raises(InvalidArgumentError, match="epsilon"):
        SelfPlayTDConfig(epsilon=1.5).validate()
    assert position_code(TIC_TAC_TOE.from_moves("12")) == 1 + 2 * 3
