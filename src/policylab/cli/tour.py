"""``policylab tour``: a walk through the notes, section by section, with the numbers.

Each section is a function registered with :func:`tour_section`; later parts of the
library add their own sections (planning, Monte Carlo, TD, figures) in their modules.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.panel import Panel
from rich.progress import Progress

from policylab.cli.common import console
from policylab.tabular.common import progress_columns
from policylab.validation import check_output_dir, check_seed

__all__ = ["TourContext", "tour_command", "tour_section"]


@dataclass
class TourContext:
    """What a tour section gets: where to print, where to write figures, how quick to be."""

    console: Console
    out_dir: Path
    quick: bool
    seed: int = 0
    figures: list[Path] | None = None

    def figure(self, path: Path) -> None:
        """Record a written figure so that the tour lists it at the end."""
        if self.figures is None:
            self.figures = []
        self.figures.append(path)

    def save(self, fig: Any, name: str) -> Path:
        """Write a matplotlib figure to ``out_dir/name``, record it, and say where it went."""
        from policylab.plot import save_figure

        path = save_figure(fig, self.out_dir / name)
        self.figure(path)
        self.console.print(f"[dim]figure: {path}[/]", soft_wrap=True)
        return path


_SECTIONS: list[tuple[float, str, Callable[[TourContext], None]]] = []


def tour_section(
    order: float, title: str
) -> Callable[[Callable[[TourContext], None]], Callable[[TourContext], None]]:
    """Register a tour section; sections run in increasing ``order``."""

    def deco(fn: Callable[[TourContext], None]) -> Callable[[TourContext], None]:
        _SECTIONS.append((order, title, fn))
        return fn

    return deco


def sections() -> list[tuple[float, str, Callable[[TourContext], None]]]:
    """The registered sections in order (importing the modules that define them)."""
    _import_section_modules()
    return sorted(_SECTIONS, key=lambda x: x[0])


def _import_section_modules() -> None:
    import importlib
    import pkgutil

    import policylab.cli as pkg

    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name.startswith("tour_") and info.name != "tour":
            importlib.import_module(f"policylab.cli.{info.name}")


def tour_command(
    quick: Annotated[
        bool, typer.Option("--quick", help="A short version (about 10 seconds).")
    ] = False,
    out: Annotated[Path, typer.Option(help="Where figures are written.")] = Path("runs/tour"),
    seed: Annotated[int, typer.Option(help="Seed of every random part of the tour.")] = 0,
) -> None:
    """Walk through the notes' examples and print what they show (the `make demo` job)."""
    out = check_output_dir(out, "--out")
    seed = check_seed(seed, "--seed") or 0
    ctx = TourContext(console=console, out_dir=out, quick=quick, seed=seed)
    secs = sections()
    console.print(
        Panel.fit(
            "[bold]policylab tour[/]: the lecture notes 'Deep Reinforcement Learning', run.\n"
            f"{len(secs)} sections" + (" (quick mode)" if quick else ""),
        )
    )
    with Progress(
        *progress_columns(None), console=console, transient=True, expand=True
    ) as progress:
        task = progress.add_task("tour", total=len(secs))
        for _, title, fn in secs:
            progress.update(task, description=title)
            progress.console.rule(f"[bold cyan]{title}")
            fn(ctx)
            progress.advance(task)
    if ctx.figures:
        console.rule("[bold]Figures written")
        for p in ctx.figures:
            console.print(f"  {p}", soft_wrap=True)
    console.print("[bold green]Tour complete.[/]")
