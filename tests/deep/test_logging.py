"""The training progress bar fits an 80-column terminal."""

from __future__ import annotations

from rich.console import Console

from policylab.deep.common.logging import TrainingProgress, compact_count


def test_compact_counts() -> None:
    cases = {0: "0", 950: "950", 9_999: "9,999", 12_345: "12.3k", 99_950: "100k",
             999_499: "999k", 999_500: "1.00M", 1_234_567: "1.23M",
             12_345_678: "12.3M"}  # fmt: skip
    assert {n: compact_count(n) for n in cases} == cases


def test_progress_bar_is_not_cut_at_80_columns() -> None:
    console = Console(width=80, record=True, color_system=None)
    bar = TrainingProgress(10_000_000, start=0, console=console, description="dqn")
    bar.update(1_234_567, -12345.6)
    assert bar._progress is not None
    console.print(bar._progress.get_renderable())  # the bar's one line, as drawn
    line = console.export_text().rstrip("\n")
    assert "\n" not in line and "…" not in line and len(line) <= 80, line
    assert "1.23M/10.0M" in line and "return -12345.6" in line and "/s" in line
