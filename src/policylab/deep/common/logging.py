"""Training logs (CSV and TensorBoard) and the rich progress bar of a training run."""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from policylab.runs import atomic_write_bytes

__all__ = ["RunLogger", "TrainingProgress"]


class RunLogger:
    """Scalar metrics in ``progress.csv`` and TensorBoard event files of a run folder.

    ``progress.csv`` has one header line naming every column ever logged: when a row
    brings a new metric (DQN's ``loss`` once learning starts, ``recent_return`` after
    the first episode), the file is rewritten atomically with the new column, earlier
    rows getting empty cells. A metric that is None is an empty cell.

    Args:
        run_dir: The run's folder (created if missing).
        tensorboard: Also write TensorBoard events under ``run_dir/tb``.
        resume_step: Continue a run from its checkpoint at this env step: rows after it
            (logged after the last checkpoint, before a crash or Ctrl-C) are cut from
            the CSV and hidden from TensorBoard, so the log matches the checkpoint.
            None starts a new log (an existing ``progress.csv`` is kept and appended to).
    """

    def __init__(
        self, run_dir: str | Path, tensorboard: bool = True, resume_step: int | None = None
    ) -> None:
        self.dir = Path(run_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.csv_path = self.dir / "progress.csv"
        self._fields: list[str] = []
        if self.csv_path.exists():
            fields, rows = self._read()
            if resume_step is not None:  # rewritten: also drops a line cut by a kill
                kept = [r for r in rows if (k := _step_of(r)) is not None and k <= resume_step]
                self._rewrite(fields, kept)
            self._fields = fields
        self._tb: Any = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = None if resume_step is None else resume_step + 1
            self._tb = SummaryWriter(str(self.dir / "tb"), purge_step=purge)

    def _read(self) -> tuple[list[str], list[dict[str, str]]]:
        with self.csv_path.open(newline="") as f:
            reader = csv.DictReader(f)
            rows = [r for r in reader if None not in r and None not in r.values()]
            return list(reader.fieldnames or []), rows

    def _rewrite(self, fields: list[str], rows: list[dict[str, Any]]) -> None:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
        atomic_write_bytes(self.csv_path, buf.getvalue().encode())

    def log(self, step: int, metrics: Mapping[str, float | None]) -> None:
        """Write one row of metrics at env step ``step``."""
        row: dict[str, Any] = {"step": step}
        for k, v in metrics.items():
            row[k] = "" if v is None else v
        new = [k for k in row if k not in self._fields]
        if new or not self.csv_path.exists():
            rows: list[dict[str, Any]] = self._read()[1] if self.csv_path.exists() else []
            self._fields = self._fields + new
            self._rewrite(self._fields, [*rows, row])
        else:
            with self.csv_path.open("a", newline="") as f:
                w = csv.DictWriter(
                    f, fieldnames=self._fields, extrasaction="ignore", lineterminator="\n"
                )
                w.writerow(row)
        if self._tb is not None:
            for k, v in metrics.items():
                if v is not None and not (isinstance(v, float) and math.isnan(v)):
                    self._tb.add_scalar(k, v, step)

    def close(self) -> None:
        """Flush and close the TensorBoard writer."""
        if self._tb is not None:
            self._tb.close()
            self._tb = None


def _step_of(row: dict[str, str]) -> int | None:
    try:
        return int(float(row.get("step") or ""))
    except ValueError:
        return None


class TrainingProgress:
    """A rich progress bar of env steps with steps/s and the recent mean return.

    Used as a context manager; with ``enabled=False`` it only keeps the counters.

    Args:
        total: Step count the run trains up to.
        start: Steps already done (a resumed run).
        enabled: Whether to draw the bar.
        console: Where to draw it.
        description: Text before the bar.
    """

    def __init__(
        self,
        total: int,
        start: int = 0,
        enabled: bool = True,
        console: Console | None = None,
        description: str = "training",
    ) -> None:
        self.total, self.start, self.enabled = total, start, enabled
        self.t0 = time.perf_counter()
        self._progress: Progress | None = None
        self._task: TaskID | None = None
        if enabled:
            self._progress = Progress(
                TextColumn("[bold]{task.description}"),
                BarColumn(bar_width=16),
                TextColumn("{task.fields[steps]}"),
                TextColumn("[cyan]{task.fields[rate]}"),
                TextColumn("return [green]{task.fields[ret]}"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=console,
            )
            self._task = self._progress.add_task(
                description,
                total=total,
                completed=start,
                steps=_steps_text(start, total),
                rate="",
                ret="-",
            )

    def __enter__(self) -> TrainingProgress:
        if self._progress is not None:
            self._progress.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._progress is not None:
            self._progress.stop()

    def steps_per_second(self, steps: int) -> float:
        """Mean env steps per second since the bar started."""
        dt = time.perf_counter() - self.t0
        return (steps - self.start) / dt if dt > 0 else 0.0

    def update(self, steps: int, recent_return: float | None) -> None:
        """Move the bar to ``steps`` and show the recent mean episode return."""
        if self._progress is not None and self._task is not None:
            ret = "-" if recent_return is None else f"{recent_return:.1f}"
            self._progress.update(
                self._task,
                completed=steps,
                steps=_steps_text(steps, self.total),
                rate=f"{compact_count(self.steps_per_second(steps))}/s",
                ret=ret,
            )


def compact_count(n: float) -> str:
    """A count in at most 6 characters: ``950``, ``12.3k``, ``1.25M``."""
    if n < 10_000:
        return f"{n:,.0f}"
    if n < 999_500:
        return f"{n / 1e3:.1f}k" if n < 99_950 else f"{n / 1e3:.0f}k"
    return f"{n / 1e6:.2f}M" if n < 9.995e6 else f"{n / 1e6:.1f}M"


def _steps_text(steps: int, total: int) -> str:
    return f"{compact_count(steps)}/{compact_count(total)}"
