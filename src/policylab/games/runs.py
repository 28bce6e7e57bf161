"""What is game-specific about a game learner's run folder.

The folder rules themselves (a lock, no silent reuse, atomic writes, stale temporary
files removed, Ctrl-C that saves) are those of every training command, in
:class:`policylab.runs.RunFolder`; this module adds only what a board-game run
needs on top: that a resumed folder holds a run of the same learner on the same
game, and reading such a folder's ``run.json`` to play its learner.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from policylab.exceptions import CheckpointError, RunFolderError
from policylab.runs import CHECKPOINT, RUN_JSON, RUN_MARKERS, RunFolder

__all__ = ["CHECKPOINT", "game_run", "read_run_json"]


@contextlib.contextmanager
def game_run(
    run_dir: str | os.PathLike[str] | RunFolder, *, resume: bool, algo: str, game: str
) -> Iterator[RunFolder]:
    """The run folder of ``algo`` learning ``game``, held by this process while the block runs.

    Args:
        run_dir: A path (opened and closed here), or a :class:`~policylab.runs.RunFolder`
            (opened here unless it is open already, as the command line does).
        resume: Continue the run in the folder (else a new run).
        algo: The learner (``"selfplay-td"``, ``"alphazero"``).
        game: The game's name.

    Raises:
        RunFolderError: If the folder is in use, holds a run and ``resume`` is False,
            holds none with ``resume``, holds a run of another learner or game, or
            stopped before its first checkpoint.
    """
    run = (
        run_dir
        if isinstance(run_dir, RunFolder)
        else RunFolder(
            run_dir, resume=resume, markers=RUN_MARKERS, command=f"policylab train {algo} {game}"
        )
    )
    own = not run.is_open
    if own:
        run.open()
    try:
        if run.resume:
            info = run.info or {}
            was_algo, was_game = info.get("algo"), info.get("game", info.get("env_id"))
            if was_algo is not None and (was_algo, was_game) != (algo, game):
                raise RunFolderError(
                    f"{str(run.path)!r} is a {was_algo} run on {was_game}, not {algo} on "
                    f"{game}; --resume continues a run as it is: policylab train {was_algo} "
                    f"{was_game} --out {run.path} --resume"
                )
            if not run.file(CHECKPOINT).is_file():
                raise RunFolderError(
                    f"{str(run.path)!r} holds a run that stopped before its first checkpoint; "
                    "there is nothing to resume: remove the folder or choose another --out"
                )
        yield run
    finally:
        if own:
            run.close()


def read_run_json(run_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``run.json`` of a game learner's run folder (what :func:`load_player` reads).

    Raises:
        CheckpointError: If the folder holds no ``run.json`` or one that names no
            algorithm and game.
        RunFolderError: If ``run.json`` is not a JSON object.
    """
    rd = Path(run_dir)
    if not (rd / RUN_JSON).is_file():
        raise CheckpointError(f"{str(rd)!r} is not a game learner's run folder (no {RUN_JSON})")
    doc = RunFolder(rd).read_json(RUN_JSON)
    if "algo" not in doc or "game" not in doc:
        raise CheckpointError(f"{str(rd / RUN_JSON)!r} does not name an algorithm and a game")
    return doc
