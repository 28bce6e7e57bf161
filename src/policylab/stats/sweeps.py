"""Reading sweep folders (``sweep.json``) into score matrices, one task per folder.

``policylab sweep`` and ``policylab tune`` keep, in their output folder, a file
``sweep.json``: the experiment (algorithm, problem, the metric and whether higher is
better) and every trial, with its configuration label, seed, status, final metrics and
learning curve. A folder is one task; a configuration that appears in several folders
gives a (runs x tasks) matrix, its runs matched by seed. Everything else in a folder
(Ray's experiment folder, the trials' run folders) is left alone.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from policylab.exceptions import CheckpointError, InvalidArgumentError, RunFolderError
from policylab.stats.aggregates import FloatArray
from policylab.validation import check_number, fmt_number

__all__ = [
    "SWEEP_FILE",
    "SWEEP_KIND",
    "SWEEP_VERSIONS",
    "ScoreMatrix",
    "Sweep",
    "SweepRun",
    "read_sweep",
    "score_matrices",
]

#: The file a sweep folder holds.
SWEEP_FILE = "sweep.json"
#: Its ``kind``.
SWEEP_KIND = "policylab-sweep"
#: The ``version`` numbers this reader understands.
SWEEP_VERSIONS = (1,)
#: A trial whose scores count: it ran to its end.
FINISHED = "TERMINATED"


@dataclass(frozen=True, eq=False)
class SweepRun:
    """One (configuration, seed) of a sweep.

    Attributes:
        config_label: The configuration, as ``"alpha=0.1,epsilon=0.2"`` (or ``"default"``).
        seed: The seed it ran with.
        status: ``"TERMINATED"`` (finished), ``"ERROR"``, ``"RUNNING"`` or ``"PENDING"``.
        metrics: Its final metrics, by name (NaN where a value was not a number).
        curve_x: Steps or episodes of its learning curve (empty if none).
        curve_y: The metric at each point of the curve.
        x_label: What ``curve_x`` counts ("episode", "step").
    """

    config_label: str
    seed: int
    status: str
    metrics: dict[str, float]
    curve_x: FloatArray
    curve_y: FloatArray
    x_label: str = ""


@dataclass(frozen=True, eq=False)
class Sweep:
    """The content of one sweep folder's ``sweep.json``.

    Attributes:
        folder: The folder.
        command: ``"sweep"`` or ``"tune"``.
        algorithm: The algorithm's name.
        problem: The problem (the task) it ran on.
        metric: The name of the score in each run's metrics.
        mode: ``"max"`` (higher is better) or ``"min"``.
        metric_description: What the score measures, for people.
        runs: Every (configuration, seed) entry, in file order.
    """

    folder: Path
    command: str
    algorithm: str
    problem: str
    metric: str
    mode: str
    metric_description: str
    runs: tuple[SweepRun, ...] = field(default_factory=tuple)


@dataclass(frozen=True, eq=False)
class ScoreMatrix:
    """The scores of one configuration over seeds (runs) and folders (tasks).

    Attributes:
        label: The configuration label.
        tasks: One name per column (the problem of each folder).
        seeds: One seed per row: the seeds finished in every task.
        scores: (runs, tasks) scores (normalised if asked).
        curves: Per task, the learning curves of the matched runs: ``(x, y)`` pairs.
        dropped: Finished runs left out because their seed did not finish in every task.
    """

    label: str
    tasks: tuple[str, ...]
    seeds: tuple[int, ...]
    scores: FloatArray
    curves: dict[str, list[tuple[FloatArray, FloatArray]]]
    dropped: int = 0


def _bad(path: Path, what: str) -> CheckpointError:
    return CheckpointError(f"{str(path)!r} is not a readable sweep file: {what}")


def _text(doc: Mapping[str, Any], key: str, path: Path, default: str | None = None) -> str:
    value = doc.get(key, default)
    if not isinstance(value, str):
        given = "missing" if key not in doc else f"{type(value).__name__} {value!r}"
        raise _bad(path, f"{key!r} must be a string; it is {given}")
    return value


def _float(value: Any) -> float:
    """A metric as a float: NaN where it is not a finite number (None, a string, inf)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return math.nan
    x = float(value)
    return x if math.isfinite(x) else math.nan


def _curve(run: Mapping[str, Any], path: Path, where: str) -> tuple[FloatArray, FloatArray, str]:
    curve = run.get("curve") or {}
    if not isinstance(curve, Mapping):
        raise _bad(path, f"{where}: 'curve' must be an object with 'x' and 'y'")
    xs, ys = curve.get("x") or [], curve.get("y") or []
    try:
        x = np.asarray(xs, dtype=np.float64)
        y = np.asarray([_float(v) for v in ys], dtype=np.float64)
    except (TypeError, ValueError):
        raise _bad(path, f"{where}: the curve's 'x' and 'y' must be lists of numbers") from None
    if x.ndim != 1 or x.shape != y.shape:
        raise _bad(
            path,
            f"{where}: the curve has {x.size} x values and {y.size} y values; expected one y per x",
        )
    label = curve.get("x_label", "")
    return x, y, label if isinstance(label, str) else ""


def _run(entry: Any, path: Path, i: int) -> SweepRun:
    where = f"trials[{i}]"
    if not isinstance(entry, Mapping):
        raise _bad(path, f"{where} must be an object; it is {type(entry).__name__}")
    label = entry.get("config_label")
    if not isinstance(label, str) or not label:
        raise _bad(path, f"{where} has no 'config_label' (a non-empty string)")
    seed = entry.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise _bad(path, f"{where} ({label}) has seed {seed!r}; expected an integer")
    status = entry.get("status", "")
    if not isinstance(status, str):
        raise _bad(path, f"{where} ({label}, seed {seed}) has status {status!r}")
    metrics = entry.get("metrics") or {}
    if not isinstance(metrics, Mapping):
        raise _bad(path, f"{where} ({label}, seed {seed}): 'metrics' must be an object")
    x, y, x_label = _curve(entry, path, f"{where} ({label}, seed {seed})")
    return SweepRun(
        label, seed, status, {str(k): _float(v) for k, v in metrics.items()}, x, y, x_label
    )


def read_sweep(folder: str | Path) -> Sweep:
    """Read a sweep folder's ``sweep.json``.

    Args:
        folder: A folder written by ``policylab sweep`` or ``policylab tune`` (or the
            ``sweep.json`` file itself).

    Raises:
        RunFolderError: The folder does not exist, holds no ``sweep.json``, or holds one
            of another kind or an unsupported version.
        CheckpointError: The file is not valid JSON or an entry is malformed.
    """
    p = Path(folder)
    if p.is_file() and p.name == SWEEP_FILE:
        p = p.parent
    if not p.exists():
        raise RunFolderError(f"{str(p)!r} does not exist; expected a sweep folder")
    if not p.is_dir():
        raise RunFolderError(f"{str(p)!r} is a file; expected a sweep folder holding {SWEEP_FILE}")
    path = p / SWEEP_FILE
    if not path.is_file():
        raise RunFolderError(
            f"{str(p)!r} holds no {SWEEP_FILE}; expected a folder written by `policylab sweep` "
            "or `policylab tune`"
        )
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise _bad(path, "it is not UTF-8 text") from None
    except json.JSONDecodeError as e:
        raise _bad(path, f"invalid JSON at line {e.lineno}, column {e.colno} ({e.msg})") from None
    if not isinstance(doc, Mapping) or doc.get("kind") != SWEEP_KIND:
        kind = doc.get("kind") if isinstance(doc, Mapping) else type(doc).__name__
        raise RunFolderError(
            f"{str(path)!r} is not a policylab sweep (kind {kind!r}; expected {SWEEP_KIND!r})"
        )
    version = doc.get("version")
    if version not in SWEEP_VERSIONS:
        raise RunFolderError(
            f"{str(path)!r} has version {version!r}; this policylab reads version "
            f"{', '.join(map(str, SWEEP_VERSIONS))} (a newer policylab wrote it?)"
        )
    trials = doc.get("trials")
    if not isinstance(trials, list):
        raise _bad(path, "'trials' must be a list")
    mode = _text(doc, "mode", path, "max")
    if mode not in ("max", "min"):
        raise _bad(path, f"'mode' is {mode!r}; expected 'max' or 'min'")
    return Sweep(
        folder=p,
        command=_text(doc, "command", path, "sweep"),
        algorithm=_text(doc, "algorithm", path, ""),
        problem=_text(doc, "problem", path, p.name),
        metric=_text(doc, "metric", path, "score"),
        mode=mode,
        metric_description=_text(doc, "metric_description", path, ""),
        runs=tuple(_run(t, path, i) for i, t in enumerate(trials)),
    )


def check_normalize(bounds: Any, name: str = "normalize") -> tuple[float, float]:
    """``(min, max)`` of score normalisation, min < max (also as the text ``"min,max"``)."""
    if isinstance(bounds, str):
        parts = bounds.split(",")
        if len(parts) != 2:
            raise InvalidArgumentError(
                f"{name} must be two numbers MIN,MAX (for example 0,1); got {bounds!r}"
            )
        try:
            bounds = [float(s) for s in parts]
        except ValueError:
            raise InvalidArgumentError(
                f"{name} must be two numbers MIN,MAX (for example -100,-13); got {bounds!r}"
            ) from None
    if not isinstance(bounds, Sequence) or len(bounds) != 2:
        raise InvalidArgumentError(f"{name} must be a pair (min, max); got {bounds!r}")
    lo = check_number(bounds[0], f"{name} min")
    hi = check_number(bounds[1], f"{name} max")
    if not lo < hi:
        raise InvalidArgumentError(
            f"{name} needs min < max; got min {fmt_number(lo)} and max {fmt_number(hi)}"
        )
    return lo, hi


def _task_names(sweeps: Sequence[Sweep]) -> list[str]:
    names = [s.problem or s.folder.name for s in sweeps]
    return [
        f"{n} ({s.folder.name})" if names.count(n) > 1 else n
        for n, s in zip(names, sweeps, strict=True)
    ]


def score_matrices(
    sweeps: Sequence[Sweep],
    *,
    metric: str | None = None,
    normalize: Any = None,
) -> tuple[dict[str, ScoreMatrix], list[str]]:
    """The (runs x tasks) score matrix of every configuration, one task per sweep.

    A run counts when it finished (status ``TERMINATED``) with a finite score. A
    configuration's rows are the seeds finished in every task it appears in, in
    increasing order; a seed missing from one task is left out of all (said in the notes).
    A configuration missing from some task is left out too: its matrix would not cover
    the same tasks as the others. A (configuration, seed) listed twice in one folder
    (tuning may try one configuration twice) counts once.

    Args:
        sweeps: One :class:`Sweep` per task.
        metric: The score's name in each run's metrics (default: the sweeps' ``metric``,
            which must then be the same in all).
        normalize: ``(min, max)``: scores become (score - min) / (max - min).

    Returns:
        ``({label: ScoreMatrix}, notes)``, labels in order of first appearance; the notes
        say, in words, what was left out and why.

    Raises:
        InvalidArgumentError: No sweeps, sweeps of different metrics, bad ``normalize``,
            or no configuration with a finished run in every task.
    """
    if not sweeps:
        raise InvalidArgumentError("no sweep folders given; expected at least one")
    if metric is None:
        metrics = {s.metric for s in sweeps}
        if len(metrics) > 1:
            raise InvalidArgumentError(
                f"the sweeps measure different metrics ({', '.join(sorted(metrics))}); name the "
                "one to aggregate (--metric)"
            )
        metric = sweeps[0].metric
    bounds = None if normalize is None else check_normalize(normalize)
    tasks = _task_names(sweeps)
    notes: list[str] = []
    per_task: list[dict[str, dict[int, SweepRun]]] = []
    for sweep, task in zip(sweeps, tasks, strict=True):
        found: dict[str, dict[int, SweepRun]] = {}
        duplicates = unfinished = 0
        for run in sweep.runs:
            score = run.metrics.get(metric, math.nan)
            if run.status != FINISHED or not math.isfinite(score):
                unfinished += 1
                continue
            seeds = found.setdefault(run.config_label, {})
            if run.seed in seeds:
                duplicates += 1
                continue
            seeds[run.seed] = run
        if unfinished:
            notes.append(
                f"{task}: {unfinished} of {len(sweep.runs)} runs have no finished {metric!r} "
                "(not TERMINATED, or the metric is missing or not finite): left out"
            )
        if duplicates:
            notes.append(f"{task}: {duplicates} repeated (configuration, seed) runs counted once")
        per_task.append(found)
    labels = list(dict.fromkeys(lab for found in per_task for lab in found))
    out: dict[str, ScoreMatrix] = {}
    for label in labels:
        missing = [t for t, found in zip(tasks, per_task, strict=True) if label not in found]
        if missing:
            notes.append(
                f"{label}: no finished run on {', '.join(missing)}; left out (its scores "
                "would not cover the same tasks as the others)"
            )
            continue
        seed_sets = [set(found[label]) for found in per_task]
        common = sorted(set.intersection(*seed_sets))
        dropped = sum(len(s) for s in seed_sets) - len(common) * len(seed_sets)
        if not common:
            notes.append(f"{label}: no seed finished on every task; left out")
            continue
        if dropped:
            notes.append(
                f"{label}: {dropped} finished runs left out (their seed did not finish on "
                "every task)"
            )
        scores = np.array(
            [[found[label][seed].metrics[metric] for found in per_task] for seed in common]
        )
        if bounds is not None:
            scores = (scores - bounds[0]) / (bounds[1] - bounds[0])
        curves = {
            task: [
                (found[label][seed].curve_x, found[label][seed].curve_y)
                for seed in common
                if found[label][seed].curve_x.size
            ]
            for task, found in zip(tasks, per_task, strict=True)
        }
        out[label] = ScoreMatrix(label, tuple(tasks), tuple(common), scores, curves, dropped)
    if not out:
        raise InvalidArgumentError(
            f"no configuration has a finished {metric!r} on every task "
            f"({len(sweeps)} sweep folders, {sum(len(s.runs) for s in sweeps)} runs)"
            + (f": {notes[0]}" if notes else "")
        )
    return out, notes
