"""Training the tabular self-play learner into a run folder, and loading any game learner.

A run folder holds ``run.json`` (algorithm, game, settings, progress) and
``checkpoint.pt`` (written atomically by the deep-RL checkpoint helpers), so a
crash, Ctrl-C or kill leaves the last whole checkpoint.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from policylab.exceptions import CheckpointError, InvalidArgumentError
from policylab.games.base import Game
from policylab.games.players import Player
from policylab.games.runs import CHECKPOINT, open_run, read_run_json, write_run_json
from policylab.games.selfplay_td import SelfPlayTDConfig, TDPlayer, initial_values, train_chunk

__all__ = ["load_player", "train_selfplay_td"]


def train_selfplay_td(
    run_dir: str | Path,
    config: SelfPlayTDConfig | None = None,
    *,
    resume: bool = False,
    on_chunk: Callable[[int, int], None] | None = None,
) -> TDPlayer:
    """Learn tic-tac-toe by self-play TD into ``run_dir``; a checkpoint after every chunk.

    Args:
        run_dir: The run folder (refused if it holds a run, unless ``resume``).
        config: Settings (ignored on resume, where the run's own are used).
        resume: Continue the run in ``run_dir`` from its last checkpoint.
        on_chunk: Called with (episodes done, episodes in all) after each chunk.

    Returns:
        The greedy player of the learned table.
    """
    from policylab.deep.common.checkpoint import load_checkpoint, save_checkpoint

    with open_run(run_dir, resume=resume) as rd:
        if resume:
            meta, tensors = load_checkpoint(rd / CHECKPOINT)
            if meta.get("algo") != "selfplay-td":
                raise CheckpointError(f"{str(rd)!r} is not a selfplay-td run")
            cfg = SelfPlayTDConfig(**meta["config"])
            done = int(meta["chunks_done"])
            V = np.asarray(tensors["values"].numpy(), dtype=np.float64)
        else:
            cfg = config or SelfPlayTDConfig()
            cfg.validate()
            done = 0
            V = initial_values()
        per = cfg.episodes // cfg.chunks

        def save(chunks_done: int) -> None:
            episodes = cfg.episodes if chunks_done == cfg.chunks else chunks_done * per
            meta = {
                "algo": "selfplay-td",
                "game": "tic-tac-toe",
                "config": cfg.to_dict(),
                "chunks_done": chunks_done,
                "episodes_done": episodes,
            }
            save_checkpoint(rd / CHECKPOINT, meta, {"values": V})
            write_run_json(rd, meta)

        if done == 0:
            save(0)
        for chunk in range(done, cfg.chunks):
            train_chunk(V, cfg, chunk)  # Ctrl-C here keeps the previous chunk's checkpoint
            save(chunk + 1)
            if on_chunk is not None:
                on_chunk(
                    cfg.episodes if chunk + 1 == cfg.chunks else (chunk + 1) * per, cfg.episodes
                )
        return TDPlayer(V)


def load_player(
    run_dir: str | Path, game: Game, seed: int | np.random.Generator | None = None
) -> Player:
    """The player a game learner's run folder holds (its greedy or search policy).

    Raises:
        CheckpointError: If the folder holds no game learner's run.
        InvalidArgumentError: If the run learned another game.
    """
    rd = Path(run_dir)
    doc = read_run_json(rd)
    from policylab.deep.common.checkpoint import load_checkpoint

    if doc["game"] != game.name:
        raise InvalidArgumentError(f"run {str(rd)!r} learned {doc['game']}, not {game.name}")
    meta, tensors = load_checkpoint(rd / CHECKPOINT)
    algo = meta.get("algo")
    if algo == "selfplay-td":
        return TDPlayer(np.asarray(tensors["values"].numpy(), dtype=np.float64), name=str(rd))
    if algo == "alphazero":
        from policylab.games.alphazero import AlphaZeroPlayer

        return AlphaZeroPlayer.from_checkpoint(meta, tensors, game, name=str(rd), seed=seed)
    raise CheckpointError(f"{str(rd)!r} names an unknown game learner {algo!r}")
