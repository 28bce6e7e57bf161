"""Write one benchmark's measured table into its own section of BENCHMARKS.md."""

from __future__ import annotations

import os
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


def processor() -> str:
    """The processor's model, its widest vector unit and the cores this process may use.

    Speeds (and the ratios of two libraries whose time is mostly matrix products) differ
    between processors: an AVX-512 core multiplies float32 matrices about twice as fast
    as an AVX2 core at the same clock.
    """
    model, flags = platform.processor() or platform.machine(), set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and value.strip():
                    model = value.strip()
                elif key.strip() == "flags":
                    flags = set(value.split())
                    break
    except OSError:
        pass
    units = {"avx512f": "AVX-512", "avx2": "AVX2", "avx": "AVX"}
    unit = next((f", {name}" for flag, name in units.items() if flag in flags), "")
    total = os.cpu_count() or 1
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else total
    cores = f"{total} cores" if usable == total else f"{usable} of {total} cores usable"
    return f"{model}{unit}, {cores}"


def machine() -> str:
    """One line describing where a benchmark ran."""
    return (
        f"{platform.machine()} ({processor()}), Python {platform.python_version()}, "
        f"NumPy {np.__version__}, {date.today()}"
    )


def load_note(start: float, end: float) -> str:
    """A sentence on the machine's load (1-minute load averages) while a benchmark ran.

    At most one running job per core (the benchmark itself being one) is called quiet;
    above that the absolute figures are those of a loaded machine, and only ratios of
    runs made under the same load compare.
    """
    cores = os.cpu_count() or 1
    head = f"load average {start:.1f} at the start and {end:.1f} at the end on {cores} cores"
    if max(start, end) <= cores:
        return f"The machine was quiet: {head} (the benchmark itself is one of the jobs)."
    return (
        f"The machine was shared with other jobs: {head}, so the absolute figures are from "
        "a loaded machine (the ratios compare runs under the same load)."
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
