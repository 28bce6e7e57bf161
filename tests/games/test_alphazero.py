"""AlphaZero: PUCT on exact cases, a smoke run with resume, worker processes, bad input."""

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


def test_worker_processes_give_the_same_games(tmp_path):
    cfg = default_config("connect-four", **{**TINY, "iterations": 1, "games_per_iteration": 2})
    train_alphazero("connect-four", tmp_path / "inproc", cfg)
    cfg2 = default_config(
        "connect-four", **{**TINY, "iterations": 1, "games_per_iteration": 2, "workers": 2}
    )
    train_alphazero("connect-four", tmp_path / "workers", cfg2)
    a = (tmp_path / "inproc" / "progress.csv").read_text().splitlines()[1].split(",")
    b = (tmp_path / "workers" / "progress.csv").read_text().splitlines()[1].split(",")
    assert a[:6] == b[:6]  # losses, evaluation and positions agree; only timings differ


def test_config_errors():
    with pytest.raises(InvalidArgumentError, match="unknown alphazero setting"):
        default_config("tic-tac-toe", gamma=0.9)
    with pytest.raises(InvalidArgumentError, match="simulations must be a positive integer"):
        default_config("tic-tac-toe", simulations=0)
    with pytest.raises(InvalidArgumentError, match="noise_fraction"):
        default_config("connect-four", noise_fraction=2.0)
    with pytest.raises(InvalidArgumentError, match="random_openings"):
        default_config("tic-tac-toe", random_openings=1.5)
