"""The Ray Tune function trainables: a trial of :mod:`policylab.experiments.trials` on a worker.

A trial's configuration holds the experiment (``_spec``), the sweep folder (``_out``),
the seed of a deep sweep trial (``_seed``), test hooks (``_hooks``) and the swept or
tuned values. A trial keeps its files in ``OUT/trials/TRIAL_ID/``:

- ``result.json``, its final result, written atomically before the final report; a
  trial that finds it (a driver killed after the trial finished, then resumed) reports
  it again instead of running again, so nothing finished is computed twice.
- For deep trials, one run folder per seed (``seed-K/``: ``checkpoint.pt``, ``run.json``,
  ``progress.csv``, ``curve.json``). Each segment's checkpoint files are reported to Tune
  as the trial's checkpoint; a trial retried after its worker died copies them back and
  continues from there.

Test hooks (set by the driver from environment variables, never by a user flag):
``crash_once`` (a path: a deep trial whose path does not exist yet creates it and kills
its own worker right after its first checkpoint) and ``trace`` (a path: every trial
appends its id there when it has computed its result) and ``delay`` (seconds a trial
waits before it computes, so that a test can stop the driver between two trials).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from policylab.experiments.spec import ExperimentSpec
from policylab.experiments.trials import CHECKPOINT_FILES, run_deep, run_tabular
from policylab.runs import atomic_write_bytes

__all__ = [
    "RESULT_JSON",
    "deep_trainable",
    "for_tune",
    "per_seed",
    "swept_config",
    "tabular_trainable",
    "trial_seeds",
]

RESULT_JSON = "result.json"


def swept_config(spec: ExperimentSpec, config: dict[str, Any]) -> dict[str, Any]:
    """The swept (sweep) or tuned (tune) values of a trial's configuration, in spec order."""
    keys = list(spec.grid) if spec.command == "sweep" else list(spec.space)
    return {k: _plain(config[k]) for k in keys if k in config}


def _plain(v: Any) -> Any:
    """A sampled value as plain JSON data (NumPy scalars from a searcher become numbers)."""
    item = getattr(v, "item", None)
    return item() if callable(item) else v


def trial_seeds(spec: ExperimentSpec, config: dict[str, Any]) -> list[int]:
    """The seeds a trial runs: its own one (a deep sweep trial), else every seed of the spec."""
    return [int(config["_seed"])] if "_seed" in config else list(spec.seeds)


def _context(config: dict[str, Any]) -> tuple[ExperimentSpec, Path, dict[str, Any]]:
    from ray import tune

    spec = ExperimentSpec.from_json(config["_spec"])
    folder = Path(config["_out"]) / "trials" / tune.get_context().get_trial_id()
    folder.mkdir(parents=True, exist_ok=True)
    return spec, folder, dict(config.get("_hooks") or {})


def _node() -> dict[str, Any]:
    import ray

    return {"node_id": ray.get_runtime_context().get_node_id()}


def _finish(folder: Path, result: dict[str, Any], hooks: dict[str, Any]) -> None:
    """Keep the final result (before reporting it) and note it in the trace hook."""
    atomic_write_bytes(folder / RESULT_JSON, json.dumps(result).encode())
    if hooks.get("trace"):
        with open(hooks["trace"], "a") as f:
            f.write(folder.name + "\n")


def _replay(folder: Path) -> dict[str, Any] | None:
    """The kept final result of a trial that already finished, if any."""
    path = folder / RESULT_JSON
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return doc if isinstance(doc, dict) else None


def for_tune(result: dict[str, Any]) -> dict[str, Any]:
    """A result as reported to Tune: scalars, and the per-seed part as one JSON string.

    (Tune's loggers take scalars; a string passes through them untouched.)
    """
    return {**result, "per_seed": json.dumps(result.get("per_seed", []))}


def per_seed(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The per-seed part of a result, reported (a JSON string) or kept (a list)."""
    got = result.get("per_seed", [])
    if isinstance(got, str):
        try:
            got = json.loads(got)
        except json.JSONDecodeError:
            return []
    return got if isinstance(got, list) else []


def tabular_trainable(config: dict[str, Any]) -> None:
    """A Tune trial: one tabular configuration, all its seeds in one call."""
    from ray import tune

    spec, folder, hooks = _context(config)
    result = _replay(folder)
    if result is None:
        time.sleep(float(hooks.get("delay", 0)))
        result = {
            **run_tabular(spec, swept_config(spec, config), trial_seeds(spec, config), folder),
            **_node(),
        }
        _finish(folder, result, hooks)
    tune.report(for_tune(result))


def deep_trainable(config: dict[str, Any]) -> None:
    """A Tune trial: deep runs of one configuration, checkpointed and reported per segment."""
    from ray import tune

    spec, folder, hooks = _context(config)
    kept = _replay(folder)
    if kept is not None:
        tune.report(for_tune(kept))
        return
    seeds = trial_seeds(spec, config)
    checkpoint = tune.get_checkpoint()
    if checkpoint is not None:  # a retried or resumed trial: back to its last checkpoint
        with checkpoint.as_directory() as d:
            for seed in seeds:
                for name in CHECKPOINT_FILES:
                    src = Path(d) / f"seed-{seed}" / name
                    if src.is_file():
                        atomic_write_bytes(folder / f"seed-{seed}" / name, src.read_bytes())

    def on_segment(result: dict[str, Any]) -> None:
        result = {**result, **_node()}
        if result["finished"]:
            _finish(folder, result, hooks)
        with tempfile.TemporaryDirectory(prefix="policylab-ckpt-") as tmp:
            for seed in seeds:
                (Path(tmp) / f"seed-{seed}").mkdir()
                for name in CHECKPOINT_FILES:
                    src = folder / f"seed-{seed}" / name
                    if src.is_file():
                        shutil.copyfile(src, Path(tmp) / f"seed-{seed}" / name)
            tune.report(for_tune(result), checkpoint=tune.Checkpoint.from_directory(tmp))
        crash = hooks.get("crash_once")
        if crash and not result["finished"] and not Path(crash).exists():
            Path(crash).write_text(folder.name + "\n")
            os._exit(3)  # the worker dies as a killed or lost node would

    run_deep(spec, swept_config(spec, config), seeds, folder, on_segment)
