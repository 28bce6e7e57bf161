"""Training logs (CSV and TensorBoard) and the rich progress bar of a training run."""

from __future__ import annotations

import csv
import math
import time
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

__all__ = ["RunLogger", "TrainingProgress"]


class RunLogger:
    """Appends scalar metrics to ``progress.csv`` and TensorBoard event files in a run folder.

    The CSV columns are those of the first row written (later keys are dropped from
    the CSV but still go to TensorBoard); a resumed run appends to the same file.

    Args:
        run_dir: The run's folder (created if missing).
        tensorboard: Also write TensorBoard events under ``run_dir/tb``.
    """

    def __init__(self, run_dir: str | Path, tensorboard: bool = True) -> None:
        self.dir = Path(run_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.csv_path = self.dir / "progress.csv"
        self._fields: list[str] | None = None
        if self.csv_path.exists():
            with self.csv_path.open() as f:
                header = f.readline().strip()
            self._fields = header.split(",") if header else None
        self._tb: Any = None
        if tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            self._tb = SummaryWriter(str(self.dir / "tb"))

    def log(self, step: int, metrics: dict[str, float]) -> None:
        """Write one row of metrics at env step ``step``."""
        row = {"step": step, **{k: v for k, v in metrics.items() if v is not None}}
        new = self._fields is None
        if new:
            self._fields = list(row)
        with self.csv_path.open("a", newline="") as f:
            w = csv.DictWriter(f, fieldnames=self._fields or [], extrasaction="ignore")
            if new:
                w.writeheader()
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
                BarColumn(),
                TextColumn("{task.completed:,.0f}/{task.total:,.0f} steps"),
                TextColumn("[cyan]{task.fields[sps]:>7,.0f} steps/s"),
                TextColumn("return [green]{task.fields[ret]}"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=console,
            )
            self._task = self._progress.add_task(
                description, total=total, completed=start, sps=0.0, ret="-"
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
                self._task, completed=steps, sps=self.steps_per_second(steps), ret=ret
            )
