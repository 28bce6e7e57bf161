"""The run folder of a game learner: one process at a time, never reused silently.

Everything a learner writes goes through :func:`open_run`, so that the folder rules
(a lock, refusal of an existing run without ``resume``, checkpoints written
atomically) live in one place.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from policylab.exceptions import CheckpointError, InvalidArgumentError

__all__ = [
    "CHECKPOINT",
    "RUN_JSON",
    "check_run",
    "open_run",
    "read_run_json",
    "trim_log",
    "write_run_json",
]

CHECKPOINT = "checkpoint.pt"
RUN_JSON = "run.json"
_LOCK = ".lock"


def check_run(path: str | os.PathLike[str], *, resume: bool) -> None:
    """Refuse a folder that holds a run (without ``resume``) or none (with it).

    Raises:
        InvalidArgumentError: If the folder holds a run and ``resume`` is False.
        CheckpointError: If ``resume`` is True and the folder holds no checkpoint.
    """
    p = Path(path)
    has_run = (p / CHECKPOINT).exists()
    if has_run and not resume:
        raise InvalidArgumentError(
            f"{str(p)!r} already holds a run; pass --resume to continue it or --out for a new "
            "folder"
        )
    if resume and not has_run:
        raise CheckpointError(f"nothing to resume: {str(p)!r} holds no {CHECKPOINT}")


@contextlib.contextmanager
def open_run(path: str | os.PathLike[str], *, resume: bool) -> Iterator[Path]:
    """Hold the run folder ``path`` for this process while the block runs.

    Raises:
        InvalidArgumentError: If the folder holds a run and ``resume`` is False, or
            another process holds it.
        CheckpointError: If ``resume`` is True and the folder holds no checkpoint.
    """
    p = Path(path)
    check_run(p, resume=resume)
    p.mkdir(parents=True, exist_ok=True)
    fd = os.open(p / _LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InvalidArgumentError(
                f"{str(p)!r} is in use by another process (its lock is held)"
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield p
    finally:
        os.close(fd)  # closing the descriptor releases the lock


def write_run_json(run_dir: Path, doc: dict[str, Any]) -> None:
    """Atomically write ``run.json`` (what the run is; read by players and resume)."""
    from policylab.deep.common.checkpoint import atomic_write_bytes

    atomic_write_bytes(run_dir / RUN_JSON, (json.dumps(doc, indent=2) + "\n").encode())


def read_run_json(run_dir: Path) -> dict[str, Any]:
    """The ``run.json`` of a game learner's run folder.

    Raises:
        CheckpointError: If it is missing or malformed.
    """
    f = Path(run_dir) / RUN_JSON
    try:
        doc = json.loads(f.read_text())
    except FileNotFoundError:
        raise CheckpointError(
            f"{str(run_dir)!r} is not a game learner's run folder (no {RUN_JSON})"
        ) from None
    except (OSError, ValueError) as e:
        raise CheckpointError(f"{str(f)!r} is not valid JSON: {e}") from None
    if not isinstance(doc, dict) or "algo" not in doc or "game" not in doc:
        raise CheckpointError(f"{str(f)!r} does not name an algorithm and a game")
    return doc


def trim_log(run_dir: Path, last_step: int) -> None:
    """Drop the rows of ``progress.csv`` past ``last_step`` (written after the last checkpoint).

    A resumed run then logs on from its checkpoint, so the log always matches it.
    """
    from policylab.deep.common.checkpoint import atomic_write_bytes

    f = Path(run_dir) / "progress.csv"
    if not f.exists():
        return
    lines = f.read_text().splitlines(keepends=True)
    keep = lines[:1] + [ln for ln in lines[1:] if int(ln.split(",", 1)[0]) <= last_step]
    if len(keep) != len(lines):
        atomic_write_bytes(f, "".join(keep).encode())
