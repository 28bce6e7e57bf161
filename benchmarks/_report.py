"""Write one benchmark's measured table into its own section of BENCHMARKS.md."""

from __future__ import annotations

import platform
import re
from datetime import date
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS_MD = ROOT / "BENCHMARKS.md"
HEADER = (
    "# policylab benchmarks\n\n"
    "Every table below is written by a script in `benchmarks/` (run them all with "
    "`make bench`); each section names the command that produced it. Measured on the "
    "project's machine (2 cores, 24 GiB, no GPU) unless the section says otherwise.\n"
)


def machine() -> str:
    """One line describing where a benchmark ran."""
    return (
        f"{platform.machine()}, Python {platform.python_version()}, "
        f"NumPy {np.__version__}, {date.today()}"
    )


def write_section(name: str, command: str, body: str) -> None:
    """Replace (or add) the section ``name`` of BENCHMARKS.md with ``body``.

    Writes to a temporary file and renames it, so a crash never leaves a half-written
    BENCHMARKS.md.
    """
    text = BENCHMARKS_MD.read_text() if BENCHMARKS_MD.exists() else HEADER
    block = (
        f"<!-- {name}:start -->\n## {name}\n\nCommand: `{command}`  \nMachine: {machine()}\n\n"
        f"{body.strip()}\n<!-- {name}:end -->"
    )
    pattern = re.compile(
        rf"<!-- {re.escape(name)}:start -->.*?<!-- {re.escape(name)}:end -->", re.S
    )
    text = (
        pattern.sub(lambda _: block, text)
        if pattern.search(text)
        else text.rstrip() + "\n\n" + block + "\n"
    )
    tmp = BENCHMARKS_MD.with_suffix(".md.tmp")
    tmp.write_text(text)
    tmp.replace(BENCHMARKS_MD)
