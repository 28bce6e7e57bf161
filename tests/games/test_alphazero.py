"""AlphaZero: PUCT on exact cases, a smoke run with resume, bad input.

Worker processes and Ray tasks are held against self-play in this process in
``test_alphazero_ray.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from policylab.exceptions import InvalidArgumentError, RunFolderError
from policylab.games import CONNECT_FOUR, TIC_TAC_TOE, make_player

pytest.importorskip("torch")

from policylab.games.alphazero import PUCT, default_config, train_alphazero

TINY = dict(
    iterations=2,
    games_per_iteration=4,
    simulations=8,
    eval_simulations=8,
    train_steps=5,
    batch_size=32,
    eval_games=2,
    workers=0,
    channels=8,
    blocks=1,
)


def uniform(states):
    legal = np.stack([s.action_mask() for s in states]).astype(float)
    return legal / legal.sum(axis=1, keepdims=True), np.zeros(len(states))


def test_puct_with_uniform_priors_finds_the_win_and_the_block():
    # with no knowledge at all, the search still sees the finished games at the leaves
    counts = PUCT(uniform, 400).visit_counts(TIC_TAC_TOE.from_moves("1527"))  # X wins at 3
    assert int(np.argmax(counts)) == 2 and counts.sum() == 400
    counts = PUCT(uniform, 2000).visit_counts(CONNECT_FOUR.from_moves("12121"))  # O blocks 1
    assert int(np.argmax(counts)) == 0


def test_smoke_run_resume_and_player(tmp_path):
    run = tmp_path / "az"
    cfg = default_config("tic-tac-toe", **TINY)
    train_alphazero("tic-tac-toe", run, cfg)
    rows = (run / "progress.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + 2 and rows[0].startswith("step,loss_value,loss_policy")
    assert json.loads((run / "run.json").read_text())["iteration"] == 2
    with pytest.raises(RunFolderError, match="already holds a run"):
        train_alphazero("tic-tac-toe", run, cfg)
    train_alphazero("tic-tac-toe", run, resume=True, iterations=3)
    assert json.loads((run / "run.json").read_text())["iteration"] == 3
    assert len((run / "progress.csv").read_text().strip().splitlines()) == 1 + 3
    player = make_player(str(run), TIC_TAC_TOE)
    s = TIC_TAC_TOE.from_moves("15")
    assert player.choose(s) in s.legal_actions()
    # same seed, same run: a second run of the first two iterations gives the same losses
    other = tmp_path / "az2"
    train_alphazero("tic-tac-toe", other, cfg)
    a = (run / "progress.csv").read_text().splitlines()[1].split(",")[:3]
    b = (other / "progress.csv").read_text().splitlines()[1].split(",")[:3]
    assert a == b


def test_config_errors():
    with pytest.raises(InvalidArgumentError, match="unknown alphazero setting"):
        default_config("tic-tac-toe", gamma=0.9)
    with pytest.raises(InvalidArgumentError, match="simulations must be a positive integer"):
        default_config("tic-tac-toe", simulations=0)
    with pytest.raises(InvalidArgumentError, match="noise_fraction"):
        default_config("connect-four", noise_fraction=2.0)
    with pytest.raises(InvalidArgumentError, match="random_openings"):
        default_config("tic-tac-toe", random_openings=1.5)


def test_searching_side_by_side_equals_one_by_one():
    states = [TIC_TAC_TOE.from_moves(m) for m in ("", "15", "1527", "5")] + [
        CONNECT_FOUR.from_moves("4453")
    ]
    for group in (states[:4], states[4:]):
        seeds = range(len(group))
        together = PUCT(uniform, 60).visit_counts_many(
            group, (1.0, 0.25), [np.random.default_rng(s) for s in seeds]
        )
        for s, seed, row in zip(group, seeds, together, strict=True):
            alone = PUCT(uniform, 60).visit_counts(s, (1.0, 0.25), np.random.default_rng(seed))
            assert np.array_equal(row, alone) and row.sum() == 60


def test_side_by_side_arena_plays_the_same_games_as_one_by_one():
    import torch

    from policylab.games.alphazero import AlphaZeroPlayer, make_network
    from policylab.games.arena import arena, play_game

    torch.manual_seed(0)
    a = AlphaZeroPlayer(make_network(TIC_TAC_TOE, 8, 1), TIC_TAC_TOE, 12, 1.5, name="a")
    b = AlphaZeroPlayer(make_network(TIC_TAC_TOE, 8, 1), TIC_TAC_TOE, 12, 1.5, name="b")
    ends = []
    res = arena(TIC_TAC_TOE, a, b, 4, finals=ends)
    for i, end in enumerate(ends):
        first, second = (a, b) if i % 2 == 0 else (b, a)
        assert end.moves == play_game(first, second, TIC_TAC_TOE.initial()).moves
    assert res.games == 4


@pytest.mark.parametrize("game", [TIC_TAC_TOE, CONNECT_FOUR])
def test_board_symmetries_map_positions_and_optimal_moves(game):
    from policylab.games import best_moves
    from policylab.games.alphazero import symmetries, transform_board

    syms = symmetries(game)
    assert len(syms) == (8 if game is TIC_TAC_TOE else 2)
    c4_lines = ("4444555566", "6122267511345422561144")
    lines = ("159", "2468", "31") if game is TIC_TAC_TOE else c4_lines
    for line in lines:
        s = game.from_moves(line)
        for turns, mirrored, perm in syms:
            inv = np.argsort(perm)  # old action -> new action
            t = game.initial()
            for m in s.moves:
                t = t.play(int(inv[m]))
            assert np.array_equal(t.encode(), transform_board(s.encode(), turns, mirrored))
            assert sorted(best_moves(t)) == sorted(int(inv[a]) for a in best_moves(s))


def test_trained_tictactoe_network_never_loses_to_perfect_play_as_x_or_o():
    """Every line of the perfect player (each of its optimal moves), AlphaZero first and second.

    The network is the best one of a run with the default settings and seed 0, made by
    ``tests/games/data/make_alphazero_ttt.py`` on the machine that wrote it (the rounding
    of the network's matrix kernels differs between processors, so the same seed can
    train another network elsewhere: BENCHMARKS.md counts the seeds that never lose); it
    plays as ``load_player`` does (the default 50 simulations per move, its most visited
    move).
    """
    from pathlib import Path

    import torch

    from policylab.games import best_moves
    from policylab.games.alphazero import AlphaZeroPlayer, make_network
    from policylab.games.arena import worst_outcome

    cfg = default_config("tic-tac-toe")
    weights = np.load(Path(__file__).parent / "data" / "alphazero_ttt.npz")
    net = make_network(TIC_TAC_TOE, cfg.channels, cfg.blocks)
    net.load_state_dict({k: torch.from_numpy(weights[k]) for k in weights.files})
    player = AlphaZeroPlayer(net, TIC_TAC_TOE, cfg.eval_simulations, cfg.c_puct)
    for me in (0, 1):
        assert worst_outcome(player, TIC_TAC_TOE.initial(), me, best_moves) == 0.0
    # the line it used to lose as O: X 4, O 1, X 9 (7 loses; 3, 5 or 6 hold the draw)
    assert player.choose(TIC_TAC_TOE.from_moves("419")) in (2, 4, 5)


def test_backend_ray_without_ray_names_the_sweep_extra(monkeypatch, tmp_path):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    cfg = default_config("tic-tac-toe", **{**TINY, "workers": 1, "backend": "ray"})
    with pytest.raises(InvalidArgumentError, match=r"needs Ray.*pip install 'policylab\[sweep\]'"):
        train_alphazero("tic-tac-toe", tmp_path / "r", cfg)
    assert not (tmp_path / "r").exists()  # refused before the run folder is touched
