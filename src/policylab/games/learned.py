"""Training the tabular self-play learner into a run folder, and loading any game learner.

A run folder holds ``run.json`` (algorithm, game, settings, progress) and
``checkpoint.pt`` (written atomically by the deep-RL checkpoint helpers), so a
crash, Ctrl-C or kill leaves the last whole checkpoint. The folder follows the rules
of every training run (:class:`policylab.runs.RunFolder`): one process at a time, never
reused without ``resume``, and Ctrl-C (or SIGTERM) stops after the chunk of games in
progress, saves, and raises :class:`~policylab.exceptions.TrainingInterrupted`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from policylab.exceptions import CheckpointError, InvalidArgumentError, TrainingInterrupted
from policylab.games.base import Game
from policylab.games.players import Player
from policylab.games.runs import CHECKPOINT, game_run, read_run_json
from policylab.games.selfplay_td import SelfPlayTDConfig, TDPlayer, initial_values, train_chunk
from policylab.runs import RUN_JSON, RunFolder

__all__ = ["load_player", "train_selfplay_td"]


def train_selfplay_td(
    run_dir: str | Path | RunFolder,
    config: SelfPlayTDConfig | None = None,
    *,
    resume: bool = False,
    on_chunk: Callable[[int, int], None] | None = None,
) -> TDPlayer:
    """Learn tic-tac-toe by self-play TD into ``run_dir``; a checkpoint after every chunk.

    Args:
        run_dir: The run folder (refused if it holds a run, unless ``resume``), a path or
            a :class:`~policylab.runs.RunFolder`.
        config: Settings (ignored on resume, where the run's own are used).
        resume: Continue the run in ``run_dir`` from its last checkpoint.
        on_chunk: Called with (episodes done, episodes in all) after each chunk.

    Returns:
        The greedy player of the learned table.

    Raises:
        RunFolderError: If the run folder is in use, holds a run (without ``resume``),
            holds none or another learner's (with it).
        TrainingInterrupted: On Ctrl-C or SIGTERM, after saving; its ``step`` counts the
            self-play games played.
    """
    from policylab.deep.common.checkpoint import load_checkpoint, save_checkpoint

    with game_run(run_dir, resume=resume, algo="selfplay-td", game="tic-tac-toe") as run:
        rd = run.path
        if run.resume:
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

        def episodes_after(chunks_done: int) -> int:
            return cfg.episodes if chunks_done == cfg.chunks else chunks_done * per

        def save(chunks_done: int) -> None:
            meta = {
                "algo": "selfplay-td",
                "game": "tic-tac-toe",
                "config": cfg.to_dict(),
                "chunks_done": chunks_done,
                "episodes_done": episodes_after(chunks_done),
            }
            save_checkpoint(rd / CHECKPOINT, meta, {"values": V})
            run.write_json(RUN_JSON, meta)

        with run.catch_interrupts():
            if done == 0:
                save(0)
            for chunk in range(done, cfg.chunks):
                if run.interrupted:  # the last chunk's checkpoint is saved
                    raise TrainingInterrupted(episodes_after(chunk), str(rd), run.signal or 2)
                train_chunk(V, cfg, chunk)
                save(chunk + 1)
                if on_chunk is not None:
                    on_chunk(episodes_after(chunk + 1), cfg.episodes)
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
