"""Run folders that never lose work and never mix two runs.

A *run folder* is what a training command writes (``policylab train``, and any
command that trains for long and keeps a checkpoint): a description ``run.json``, a
checkpoint, logs. :class:`RunFolder` holds the rules every such command follows, so
that each command states them once by using it:

- **One process at a time.** Opening a run folder takes an exclusive lock (an
  ``flock`` on ``.lock`` inside it, holding the owner's process id, host, command and
  start time). A second process that opens the same folder gets a
  :class:`~policylab.exceptions.RunFolderError` naming the owner. The operating system
  drops the lock when its process ends in any way (``kill -9`` included), so a lock
  left by a dead process is recognised as stale and taken over
  (:attr:`RunFolder.stale_owner` then says whose it was).
- **Never reused silently.** ``RunFolder(path)`` refuses a folder that already holds a
  run (any of its ``markers`` files exists) and suggests ``--resume`` or a new folder;
  ``RunFolder(path, resume=True)`` requires one and reads its ``run.json`` into
  :attr:`RunFolder.info`, for the command to check that what it is asked to continue
  is the same run.
- **Never half-written.** Files are written with :func:`atomic_write_bytes` (a temporary
  file beside the target, fsync'ed and renamed over it), so a crash leaves the old file
  or the new one. Temporary files that a killed writer left behind (``.NAME.*.tmp``)
  are removed when the folder is opened, once the lock is held.
- **Ctrl-C saves.** Inside ``with run.catch_interrupts():`` the first SIGINT (or
  SIGTERM, as sent by ``kill`` and batch schedulers) only sets
  :attr:`RunFolder.interrupted`; the training loop checks it between iterations, saves
  a checkpoint and raises :class:`~policylab.exceptions.TrainingInterrupted`, which the
  command line turns into "interrupted at step N; continue with --resume" and exit
  code 130 (143 for SIGTERM). A second signal stops at once (``KeyboardInterrupt``),
  keeping the last checkpoint.

Example:
    >>> with RunFolder("runs/ppo-CartPole-v1-s0", resume=False) as run:  # doctest: +SKIP
    ...     run.write_json("run.json", {"algo": "ppo"})
    ...     with run.catch_interrupts():
    ...         while not run.interrupted and not done():
    ...             step()

This module imports neither torch nor anything heavy: any layer may use it.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import FrameType, TracebackType
from typing import Any

from policylab.exceptions import RunFolderError

__all__ = [
    "CHECKPOINT",
    "LOCK_FILE",
    "PROGRESS_CSV",
    "RUN_JSON",
    "RUN_MARKERS",
    "RunFolder",
    "atomic_write_bytes",
]

LOCK_FILE = ".lock"
RUN_JSON = "run.json"
CHECKPOINT = "checkpoint.pt"
PROGRESS_CSV = "progress.csv"
RUN_MARKERS = (RUN_JSON, CHECKPOINT, PROGRESS_CSV)
"""Files whose presence means a folder holds a training run (deep RL or a game learner)."""


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one.

    The bytes go to a temporary file ``.NAME.*.tmp`` beside ``path``, which is fsync'ed
    and renamed over ``path`` (``os.replace`` is atomic); the folder is fsync'ed too, so
    the rename survives a power loss. A writer killed before the rename leaves only the
    temporary file, which :class:`RunFolder` removes when the folder is next opened.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)  # mkstemp makes 0600 files; keep the usual permissions
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    try:
        dir_fd = os.open(p.parent, os.O_RDONLY)
    except OSError:  # pragma: no cover - platforms without directory fds
        return
    try:
        os.fsync(dir_fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(dir_fd)


class RunFolder:
    """A run folder opened by one process: locked, checked, cleaned (a context manager).

    Args:
        path: The folder (created if missing).
        resume: False: a new run (refused if the folder already holds one). True:
            continue the run in the folder (refused if there is none).
        markers: Files whose presence means the folder holds a run.
        command: What holds the lock, as shown to a second process (``"policylab train"``).

    Attributes:
        path: The folder.
        info: The run's ``run.json`` when resuming (``{}`` if it has none), else None.
        stale_owner: The lock record of a dead process whose lock was taken over, or None.
        removed_temps: Stale temporary files removed on opening.
        interrupted: Whether Ctrl-C (SIGINT) or SIGTERM came inside :meth:`catch_interrupts`.
        signal: The number of that signal, or None.

    Raises:
        RunFolderError: On entering: the path is a file or cannot be written, another
            process holds the folder, a new run meets an existing one, or a resumed
            folder holds no run.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        resume: bool = False,
        markers: Iterable[str] = (RUN_JSON,),
        command: str = "policylab",
    ) -> None:
        self.path = Path(path)
        self.resume = resume
        self.markers = tuple(markers)
        self.command = command
        self.info: dict[str, Any] | None = None
        self.stale_owner: dict[str, Any] | None = None
        self.removed_temps: list[Path] = []
        self.interrupted = False
        self.signal: int | None = None
        self._lock_fd: int | None = None

    # ------------------------------------------------------------ opening
    def __enter__(self) -> RunFolder:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def is_open(self) -> bool:
        """Whether this object holds the folder's lock."""
        return self._lock_fd is not None

    def open(self) -> None:
        """Create the folder, take its lock, apply the new-or-resume rule, clean temp files."""
        if self.is_open:
            return
        if self.path.exists() and not self.path.is_dir():
            raise RunFolderError(f"run folder {str(self.path)!r} is an existing file")
        if self.resume:  # said before anything is created; re-checked under the lock
            self._check_new_or_resume()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunFolderError(
                f"cannot create run folder {str(self.path)!r}: {e.strerror or e}"
            ) from None
        self._lock()
        try:
            self._check_new_or_resume()
            self._remove_stale_temps()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the lock (its record is cleared: a record found later means a dead owner)."""
        if self._lock_fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self._lock_fd, 0)
            with contextlib.suppress(OSError):
                os.close(self._lock_fd)  # closing the descriptor drops the flock
            self._lock_fd = None

    def _lock(self) -> None:
        import fcntl

        lock_path = self.path / LOCK_FILE
        for _ in range(10):  # retry if the lock file is replaced between open and flock
            try:
                fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise RunFolderError(
                    f"run folder {str(self.path)!r} cannot be written: {e.strerror or e}"
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                owner = _read_owner(fd)
                os.close(fd)
                raise RunFolderError(
                    f"run folder {str(self.path)!r} is in use by {_describe(owner)}; wait for "
                    "it to finish, stop it, or choose another folder"
                ) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(lock_path).st_ino
            except OSError:
                same = False
            if not same:
                os.close(fd)
                continue
            previous = _read_owner(fd)
            if previous and previous.get("pid") is not None:
                self.stale_owner = previous
            record = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "command": self.command,
                "started": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
            }
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
            self._lock_fd = fd
            return
        raise RunFolderError(f"could not lock run folder {str(self.path)!r}")  # pragma: no cover

    def holds_run(self) -> bool:
        """Whether the folder holds a run (one of its marker files exists)."""
        return any((self.path / m).exists() for m in self.markers)

    def _check_new_or_resume(self) -> None:
        if self.resume:
            if not self.holds_run():
                raise RunFolderError(
                    f"{str(self.path)!r} holds no run to resume (no {' or '.join(self.markers)}); "
                    "leave out --resume to start one there"
                )
            info_path = self.path / RUN_JSON
            self.info = self.read_json(RUN_JSON) if info_path.exists() else {}
        elif self.holds_run():
            raise RunFolderError(
                f"{str(self.path)!r} already holds a run; pass --resume to continue it, or "
                "choose a new folder (--out) for a new run"
            )

    def _remove_stale_temps(self) -> None:
        for p in sorted(self.path.glob(".*.tmp")):
            if p.is_file():
                with contextlib.suppress(OSError):
                    p.unlink()
                    self.removed_temps.append(p)

    # ------------------------------------------------------------ files
    def file(self, name: str) -> Path:
        """The path of ``name`` inside the run folder."""
        return self.path / name

    def write_json(self, name: str, doc: Any) -> None:
        """Write ``doc`` as indented JSON to ``name`` in the folder, atomically."""
        atomic_write_bytes(self.path / name, (json.dumps(doc, indent=2) + "\n").encode())

    def read_json(self, name: str) -> dict[str, Any]:
        """The JSON object in ``name``.

        Raises:
            RunFolderError: If the file is missing, not JSON, or not an object.
        """
        p = self.path / name
        try:
            doc = json.loads(p.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
            raise RunFolderError(f"{str(p)!r} cannot be read as JSON: {e}") from None
        if not isinstance(doc, dict):
            raise RunFolderError(f"{str(p)!r} must hold a JSON object")
        return doc

    # ------------------------------------------------------------ Ctrl-C
    @contextlib.contextmanager
    def catch_interrupts(self) -> Iterator[RunFolder]:
        """Within the block, the first SIGINT or SIGTERM sets :attr:`interrupted`.

        The caller polls :attr:`interrupted` at points where its state is whole (between
        training iterations), saves, and stops. A second signal raises
        ``KeyboardInterrupt`` at once. Outside the main thread (where Python delivers
        no signals) the block changes nothing.
        """
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        self.interrupted, self.signal = False, None

        def handler(signum: int, frame: FrameType | None) -> None:
            if self.interrupted:
                raise KeyboardInterrupt
            self.interrupted, self.signal = True, signum
            sys.stderr.write(
                "\nstopping after this iteration to save a checkpoint "
                "(Ctrl-C again to stop at once)\n"
            )
            sys.stderr.flush()

        old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield self
        finally:
            for s, h in old.items():
                signal.signal(s, h)


def _read_owner(fd: int) -> dict[str, Any]:
    try:
        raw = os.pread(fd, 4096, 0)
        doc = json.loads(raw.decode() or "{}")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return {}
    return doc if isinstance(doc, dict) else {}


def _describe(owner: dict[str, Any]) -> str:
    if not owner:
        return "another process"
    parts = [f"process {owner.get('pid')}"]
    if owner.get("host") and owner.get("host") != socket.gethostname():
        parts.append(f"on {owner['host']}")
    if owner.get("command"):
        parts.append(f"({owner['command']}, started {owner.get('started', '?')})")
    return " ".join(parts)
