"""Running an experiment on Ray Tune and keeping its sweep folder: sweep, tune, resume.

The sweep folder ``OUT`` holds:

- ``sweep.json``: the experiment and every trial's configuration, seed, status, final
  metrics and learning curve, and the aggregate statistics per configuration; written
  atomically and rewritten as trials report and finish (``policylab stats OUT`` reads it).
- ``ray/``: Ray Tune's experiment folder (its state, the trials' checkpoints), which
  ``--resume`` restores with ``Tuner.restore``.
- ``trials/TRIAL_ID/``: what each trial writes (its final result, deep run folders).

The folder belongs to one driver at a time (a lock); a new experiment refuses a folder
that is not empty, and ``--resume`` refuses one that holds no sweep.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from policylab.exceptions import RunFolderError
from policylab.experiments.ray_trials import per_seed, swept_config, trial_seeds
from policylab.experiments.spec import ExperimentSpec, build_spec, config_label
from policylab.runs import LOCK_FILE, RunFolder

__all__ = ["EXPERIMENT_DIR", "SWEEP_JSON", "resume", "run_experiment", "sweep", "tune"]

SWEEP_JSON = "sweep.json"
EXPERIMENT_DIR = "ray"
KIND = "policylab-sweep"
VERSION = 1

#: Environment variables of the test hooks (see :mod:`policylab.experiments.ray_trials`).
HOOK_ENV = {
    "crash_once": "POLICYLAB_SWEEP_CRASH_ONCE",
    "trace": "POLICYLAB_SWEEP_TRACE",
    "delay": "POLICYLAB_SWEEP_TRIAL_DELAY",
}


# ------------------------------------------------------------------ sweep.json
def trial_entries(
    spec: ExperimentSpec,
    trial_id: str,
    config: dict[str, Any],
    status: str,
    result: dict[str, Any] | None,
) -> list[dict[str, Any]]:
    """The sweep.json entries of one Tune trial: one per seed it runs."""
    swept = swept_config(spec, config)
    seeds = trial_seeds(spec, config)
    by_seed = {p["seed"]: p for p in per_seed(result or {})}
    entries = []
    for seed in seeds:
        got = by_seed.get(seed, {})
        entries.append(
            {
                "trial_id": trial_id if len(seeds) == 1 else f"{trial_id}-s{seed}",
                "tune_trial_id": trial_id,
                "config": swept,
                "config_label": config_label(swept),
                "seed": seed,
                "status": status,
                "metrics": dict(got.get("metrics", {})),
                "curve": got.get("curve", {"x": [], "y": [], "x_label": ""}),
                "node_id": (result or {}).get("node_id"),
                "iterations": (result or {}).get("training_iteration"),
            }
        )
    return entries


def statistics(trials: list[dict[str, Any]], metric: str = "score") -> dict[str, Any]:
    """Per configuration label: IQM, mean, median, optimality gap with bootstrap intervals.

    Uses :func:`policylab.stats.summarize` over the finished seeds' scores (runs x one
    task). Where that package is not installed, every configuration gets only
    ``{"runs": n, "mean": ...}``.
    """
    groups: dict[str, list[float]] = {}
    for t in trials:
        score = t["metrics"].get(metric)
        if t["status"] == "TERMINATED" and score is not None and np.isfinite(score):
            groups.setdefault(t["config_label"], []).append(float(score))
    import importlib

    try:  # the statistics layer (numpy/scipy only)
        summarize = importlib.import_module("policylab.stats").summarize
    except (ImportError, AttributeError):
        summarize = None
    out: dict[str, Any] = {}
    for label, scores in groups.items():
        arr = np.asarray(scores, dtype=np.float64)
        if summarize is not None:
            out[label] = {**summarize(arr, seed=0), "runs": len(scores)}
        else:
            out[label] = {"runs": len(scores), "mean": float(arr.mean())}
    return out


class SweepRecord:
    """The live content of ``sweep.json``: trials by Tune trial id, written atomically."""

    def __init__(self, out: Path, spec: ExperimentSpec, created: str | None = None) -> None:
        self.out = out
        self.spec = spec
        self.created = created or time.strftime("%Y-%m-%d %H:%M:%S %Z")
        self.trials: dict[str, list[dict[str, Any]]] = {}

    def load(self, doc: dict[str, Any]) -> None:
        """Take the trials of an existing sweep.json (on resume)."""
        for t in doc.get("trials", []):
            self.trials.setdefault(t.get("tune_trial_id", t["trial_id"]), []).append(t)

    def update(
        self, trial_id: str, config: dict[str, Any], status: str, result: dict[str, Any] | None
    ) -> None:
        """Record a trial's status and (if given) its latest result."""
        if result is None and trial_id in self.trials:  # keep the metrics already known
            for t in self.trials[trial_id]:
                t["status"] = status
            return
        self.trials[trial_id] = trial_entries(self.spec, trial_id, config, status, result)

    def doc(self) -> dict[str, Any]:
        """The sweep.json object."""
        trials = [t for entries in self.trials.values() for t in entries]
        trials.sort(key=lambda t: (t["config_label"], t["seed"], t["trial_id"]))
        doc: dict[str, Any] = {
            "kind": KIND,
            "version": VERSION,
            "command": self.spec.command,
            "algorithm": self.spec.algorithm,
            "problem": self.spec.problem,
            "metric": self.spec.metric,
            "mode": "max",
            "metric_description": self.spec.metric_description,
            "created": self.created,
            "spec": self.spec.to_json(),
            "trials": trials,
            "statistics": statistics(trials, self.spec.metric),
        }
        if self.spec.command == "tune":
            doc["best"] = best_configuration(trials)
        return doc

    def write(self) -> dict[str, Any]:
        """Write sweep.json atomically; returns what was written."""
        from policylab.runs import atomic_write_bytes

        doc = self.doc()
        atomic_write_bytes(self.out / SWEEP_JSON, (json.dumps(doc, indent=1) + "\n").encode())
        return doc


def best_configuration(trials: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The finished configuration with the highest mean score over its seeds."""
    by: dict[str, list[dict[str, Any]]] = {}
    for t in trials:
        if t["status"] == "TERMINATED" and t["metrics"].get("score") is not None:
            by.setdefault(t["config_label"], []).append(t)
    if not by:
        return None
    label = max(by, key=lambda k: float(np.mean([t["metrics"]["score"] for t in by[k]])))
    runs = by[label]
    return {
        "config": runs[0]["config"],
        "config_label": label,
        "score": float(np.mean([t["metrics"]["score"] for t in runs])),
        "seeds": len(runs),
    }


# -------------------------------------------------------------- Tune callback
#: The live display of the running driver (not part of the pickled Tune state).
_DISPLAY: dict[str, Any] = {}


def _make_callback(record: SweepRecord) -> Any:
    from ray.tune import Callback

    class SweepCallback(Callback):
        """Rewrites sweep.json and the live table as trials start, report and end."""

        def __init__(self, out: str, spec: dict[str, Any]) -> None:
            self.out = out
            self.spec = spec

        def _record(self) -> SweepRecord:
            return _DISPLAY["record"]  # type: ignore[no-any-return]

        def _note(self, trial: Any, status: str, result: dict[str, Any] | None = None) -> None:
            rec = self._record()
            rec.update(trial.trial_id, trial.config, status, result)
            rec.write()
            live = _DISPLAY.get("live")
            if live is not None:
                live.update(_table(rec))

        def on_trial_start(
            self, iteration: int, trials: list[Any], trial: Any, **info: Any
        ) -> None:
            self._note(trial, "RUNNING")

        def on_trial_result(
            self, iteration: int, trials: list[Any], trial: Any, result: dict[str, Any], **info: Any
        ) -> None:
            self._note(trial, "RUNNING", result)

        def on_trial_complete(
            self, iteration: int, trials: list[Any], trial: Any, **info: Any
        ) -> None:
            self._note(trial, "TERMINATED", trial.last_result or None)

        def on_trial_error(
            self, iteration: int, trials: list[Any], trial: Any, **info: Any
        ) -> None:
            self._note(trial, "ERROR")

    _DISPLAY["record"] = record
    return SweepCallback(str(record.out), record.spec.to_json())


def _table(record: SweepRecord) -> Any:
    """The live table: one row per configuration (seeds done, best and mean score)."""
    from rich.table import Table

    spec = record.spec
    trials = [t for entries in record.trials.values() for t in entries]
    rows: dict[str, list[dict[str, Any]]] = {}
    for t in trials:
        rows.setdefault(t["config_label"], []).append(t)
    done = sum(t["status"] == "TERMINATED" for t in trials)
    table = Table(
        title=f"{spec.command} {spec.algorithm} on {spec.problem}: {done} of "
        f"{_expected(spec)} runs done; score = {spec.metric_description}"
    )
    for col in ("configuration", "runs done", "running", "errors", "mean score"):
        table.add_column(col, justify="left" if col == "configuration" else "right")
    for label in sorted(rows):
        ts = rows[label]
        scores = [t["metrics"]["score"] for t in ts if t["metrics"].get("score") is not None]
        table.add_row(
            label,
            f"{sum(t['status'] == 'TERMINATED' for t in ts)}/{len(ts)}",
            str(sum(t["status"] == "RUNNING" for t in ts)),
            str(sum(t["status"] == "ERROR" for t in ts)),
            f"{np.mean(scores):.4g}" if scores else "-",
        )
    return table


def _expected(spec: ExperimentSpec) -> int:
    if spec.command == "tune":
        return spec.trials * len(spec.seeds)
    return len(spec.configurations()) * len(spec.seeds)


# ------------------------------------------------------------------ Tune setup
def _param_space(spec: ExperimentSpec, out: Path) -> dict[str, Any]:
    from ray import tune

    space: dict[str, Any] = {"_spec": spec.to_json(), "_out": str(out.resolve())}
    hooks = {k: os.environ[v] for k, v in HOOK_ENV.items() if os.environ.get(v)}
    if hooks:
        space["_hooks"] = hooks
    if spec.command == "sweep":
        for k, values in spec.grid.items():
            space[k] = tune.grid_search(values)
        if spec.trial_per_seed:  # one trial per (configuration, seed): always for deep
            space["_seed"] = tune.grid_search(spec.seeds)
        return space
    for k, d in spec.space.items():
        if d["kind"] == "loguniform":
            space[k] = tune.loguniform(d["low"], d["high"])
        elif d["kind"] == "uniform":
            space[k] = tune.uniform(d["low"], d["high"])
        elif d["kind"] == "int":
            space[k] = tune.randint(d["low"], d["high"] + 1)
        else:
            space[k] = tune.choice(d["values"])
    return space


def _trainable(spec: ExperimentSpec) -> Any:
    from ray import tune

    from policylab.experiments.ray_trials import deep_trainable, tabular_trainable

    fn = deep_trainable if spec.family == "deep" else tabular_trainable
    return tune.with_resources(fn, {"cpu": 1})


def _tune_config(spec: ExperimentSpec) -> Any:
    from ray import tune

    if spec.command == "sweep":
        # tabular trials take milliseconds: a worker process serves one trial after another
        return tune.TuneConfig(num_samples=1, reuse_actors=spec.family == "tabular")
    from ray.tune.schedulers import ASHAScheduler, FIFOScheduler, MedianStoppingRule
    from ray.tune.search.optuna import OptunaSearch

    searcher = OptunaSearch(metric=spec.metric, mode="max", seed=spec.search_seed)
    scheduler: Any
    if spec.scheduler == "asha":
        scheduler = ASHAScheduler(metric=spec.metric, mode="max", grace_period=1, max_t=10**6)
    elif spec.scheduler == "median":
        scheduler = MedianStoppingRule(metric=spec.metric, mode="max", grace_period=1)
    else:
        scheduler = FIFOScheduler()  # type: ignore[no-untyped-call]
    return tune.TuneConfig(
        search_alg=searcher,
        scheduler=scheduler,
        num_samples=spec.trials,
        reuse_actors=spec.family == "tabular",
    )


def _open_folder(out: Path, resume: bool, command: str) -> RunFolder:
    """The sweep folder, locked; refuses a non-empty non-sweep folder, or resuming a non-sweep."""
    out = Path(out)
    if not resume and out.is_dir() and not (out / SWEEP_JSON).exists():
        others = [p.name for p in out.iterdir() if p.name != LOCK_FILE]
        if others:
            raise RunFolderError(
                f"{str(out)!r} is not empty and holds no sweep ({', '.join(sorted(others)[:3])}"
                f"{', ...' if len(others) > 3 else ''}); choose a new or empty folder for --out"
            )
    folder = RunFolder(out, resume=resume, markers=(SWEEP_JSON,), command=command)
    folder.open()
    return folder


def _read_sweep(folder: RunFolder) -> dict[str, Any]:
    doc = folder.read_json(SWEEP_JSON)
    if doc.get("kind") != KIND or not isinstance(doc.get("spec"), dict):
        folder.close()
        raise RunFolderError(
            f"{str(folder.path)!r} holds a {SWEEP_JSON} that is not a policylab sweep; "
            "--resume continues a folder written by `policylab sweep` or `policylab tune`"
        )
    if not (folder.path / EXPERIMENT_DIR).is_dir():
        folder.close()
        raise RunFolderError(
            f"{str(folder.path)!r} has no Ray Tune experiment ({EXPERIMENT_DIR}/) to resume"
        )
    return doc


def run_experiment(
    spec: ExperimentSpec | None,
    out: str | os.PathLike[str],
    *,
    resume: bool = False,
    address: str | None = None,
    num_cpus: int | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Run (or, with ``resume``, continue) an experiment; returns the final sweep.json object.

    Args:
        spec: The experiment (None with ``resume``: the one stored in the folder).
        out: The sweep folder.
        resume: Continue the experiment in ``out`` (Tune's restore): finished trials
            are kept, unfinished and failed ones continue from their last checkpoints.
        address: A running Ray cluster's address, or None for a local Ray.
        num_cpus: CPUs of the local Ray (default: the machine's).
        progress: Show the live table of configurations.

    Raises:
        RunFolderError: The folder is in use, not empty (new), or holds no sweep (resume).
        InvalidArgumentError: An unreachable address.
    """
    from policylab.cluster import connect, probe_address

    out_path = Path(out)
    if address is not None:  # an unreachable cluster is refused before the folder is touched
        probe_address(address)
    folder = _open_folder(out_path, resume, f"policylab {spec.command if spec else 'sweep'}")
    try:
        exp: ExperimentSpec
        if resume or spec is None:
            doc = _read_sweep(folder)
            exp = ExperimentSpec.from_json(doc["spec"])
            record = SweepRecord(out_path, exp, doc.get("created"))
            record.load(doc)
        else:
            exp = spec
        started = connect(address, num_cpus)
        if not resume:
            record = SweepRecord(out_path, exp)
            for i, config in enumerate(_pending(exp)):
                record.update(f"pending-{i}", config, "PENDING", None)
            record.write()
            record.trials.clear()
        try:
            grid = _fit(exp, out_path, record, resume, progress)
        finally:
            if started:
                import ray

                ray.shutdown()
        final = SweepRecord(out_path, exp, record.created)
        for r in grid:
            tid = str((r.metrics or {}).get("trial_id") or _trial_id(r))
            kept = _kept_result(out_path, tid)
            seen = record.trials.get(tid) or [{}]
            if r.error is not None:
                status = "ERROR"
            elif kept is not None or seen[0].get("status") == "TERMINATED":
                status = "TERMINATED"  # finished, or stopped early by the scheduler
            else:
                status = "PENDING"  # the run was stopped (Ctrl-C) before this trial ended
            result = kept or (r.metrics if (r.metrics or {}).get("per_seed") else None)
            if result is None and tid in record.trials:  # an errored trial: its last report
                final.trials[tid] = [{**t, "status": status} for t in record.trials[tid]]
            else:
                final.trials[tid] = trial_entries(exp, tid, r.config, status, result)
        return final.write()
    finally:
        folder.close()


def _trial_id(result: Any) -> str:
    """A Tune result's trial id (from its folder name ``NAME_TRIALID_INDEX_...``)."""
    parts = Path(str(result.path)).name.split("_")
    return "_".join(parts[2:4]) if len(parts) > 3 else Path(str(result.path)).name


def _kept_result(out: Path, trial_id: str) -> dict[str, Any] | None:
    """The final result a trial kept in its folder, if it finished."""
    from policylab.experiments.ray_trials import RESULT_JSON

    path = out / "trials" / trial_id / RESULT_JSON
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return doc if isinstance(doc, dict) else None


def _pending(spec: ExperimentSpec) -> list[dict[str, Any]]:
    """Placeholder configs of a new sweep (shown as PENDING until Tune starts them)."""
    if spec.command == "tune":
        return []
    configs = spec.configurations()
    if spec.trial_per_seed:
        return [{**c, "_seed": s} for c in configs for s in spec.seeds]
    return configs


def _fit(spec: ExperimentSpec, out: Path, record: SweepRecord, resume: bool, progress: bool) -> Any:
    import contextlib

    from ray import tune

    callback = _make_callback(record)
    trainable = _trainable(spec)
    if resume:
        tuner = tune.Tuner.restore(
            str((out / EXPERIMENT_DIR).resolve()), trainable=trainable, resume_errored=True
        )
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=_param_space(spec, out),
            tune_config=_tune_config(spec),
            run_config=tune.RunConfig(
                name=EXPERIMENT_DIR,
                storage_path=str(out.resolve()),
                failure_config=tune.FailureConfig(max_failures=spec.max_failures),
                checkpoint_config=tune.CheckpointConfig(num_to_keep=2),
                callbacks=[callback],
                verbose=0,
            ),
        )
    live_cm: Any = contextlib.nullcontext()
    if progress:
        from rich.console import Console
        from rich.live import Live

        live_cm = Live(_table(record), console=Console(stderr=True), refresh_per_second=4)
    with live_cm as live:
        _DISPLAY["live"] = live
        try:
            return tuner.fit()
        finally:
            _DISPLAY.pop("live", None)


# -------------------------------------------------------------- public functions
def sweep(
    algorithm: str,
    problem: str,
    *,
    seeds: int | list[int],
    out: str | os.PathLike[str],
    options: dict[str, Any] | None = None,
    grid: dict[str, list[Any]] | None = None,
    address: str | None = None,
    num_cpus: int | None = None,
    max_failures: int = 2,
    progress: bool = False,
    trial_per_seed: bool = False,
) -> dict[str, Any]:
    """Run an algorithm on a problem for every configuration of a grid and every seed.

    Every (configuration, seed) of a deep algorithm is one Ray Tune trial (checkpointed,
    retried from its checkpoint if its worker dies). A tabular configuration runs all
    its seeds in one trial (one compiled call), still recorded per seed. Seed k gives
    the run ``policylab learn`` / ``train`` gives with ``--seed k``.

    Args:
        algorithm: A tabular algorithm (``q-learning``) or a deep one (``ppo``).
        problem: The problem: a built-in name or Gymnasium id (tabular), a Gymnasium id (deep).
        seeds: How many seeds (0..n-1), or the list of seeds.
        out: The sweep folder (new or empty).
        options: The algorithm's options for every trial, by parameter
            (``{"episodes": 500, "alpha": 0.1}`` or, deep, ``{"steps": 50_000}``).
        grid: Swept keys and their values (``{"alpha": [0.1, 0.5]}``); a key with one
            value is fixed. Tabular: the learner's options; deep: config fields.
        address: A running Ray cluster (``HOST:PORT``), or None for a local Ray.
        num_cpus: CPUs of the local Ray (default: all).
        max_failures: Retries of a trial whose worker died.
        progress: Show the live table.
        trial_per_seed: Make every (configuration, seed) of a tabular algorithm its own
            trial too (slower: a trial costs far more than a tabular run; it is how the
            Ray overhead per trial is measured).

    Returns:
        The sweep.json object (``trials``, ``statistics``, ...).

    Raises:
        InvalidArgumentError: An unknown algorithm, option or key, or a bad value.
        UnknownProblemError: An unknown problem.
        RunFolderError: The folder is in use or not empty.
    """
    from policylab.experiments.trials import metric_description

    spec = build_spec(
        "sweep",
        algorithm,
        problem,
        seeds=seeds,
        options=options,
        set_values=grid,
        max_failures=max_failures,
        trial_per_seed=trial_per_seed,
    )
    spec.metric_description = metric_description(spec)
    return run_experiment(spec, out, address=address, num_cpus=num_cpus, progress=progress)


def tune(
    algorithm: str,
    problem: str,
    *,
    trials: int,
    space: dict[str, dict[str, Any]],
    out: str | os.PathLike[str],
    seeds: int | list[int] = 3,
    options: dict[str, Any] | None = None,
    fixed: dict[str, list[Any]] | None = None,
    scheduler: str = "asha",
    search_seed: int = 0,
    address: str | None = None,
    num_cpus: int | None = None,
    max_failures: int = 2,
    progress: bool = False,
) -> dict[str, Any]:
    """Search hyperparameters with Optuna's TPE sampler (Tune's ``OptunaSearch``).

    Each trial is one configuration scored over ``seeds`` seeds (their mean score).
    Tabular learners on a problem with a known model are scored against the exact
    answer (minus the RMS error of the learned values against q* or v_pi), so the
    search has a ground truth; deep learners by their mean recent return, with early
    stopping of bad trials (ASHA or the median rule) between checkpointed segments.

    Args:
        algorithm: The algorithm.
        problem: The problem.
        trials: How many configurations to try.
        space: Tuned keys and distributions, from
            :func:`~policylab.experiments.spec.parse_distribution`.
        out: The sweep folder (new or empty).
        seeds: Seeds every configuration is scored over.
        options: The algorithm's options for every trial.
        fixed: Keys fixed to one value (``{"n_envs": [8]}``).
        scheduler: ``"asha"``, ``"median"`` or ``"none"``.
        search_seed: Seed of the sampler.
        address: A running Ray cluster, or None for a local Ray.
        num_cpus: CPUs of the local Ray.
        max_failures: Retries of a trial whose worker died.
        progress: Show the live table.

    Returns:
        The sweep.json object, with ``best`` (the best configuration found).
    """
    from policylab.exceptions import InvalidArgumentError
    from policylab.experiments.trials import metric_description
    from policylab.validation import check_choice, check_count

    check_choice(scheduler, ("asha", "median", "none"), "--scheduler")
    if not space:
        raise InvalidArgumentError("tune needs at least one --param NAME=DIST to search")
    spec = build_spec(
        "tune",
        algorithm,
        problem,
        seeds=seeds,
        options=options,
        set_values=fixed,
        space=space,
        trials=check_count(trials, "--trials"),
        scheduler=scheduler,
        max_failures=max_failures,
        search_seed=search_seed,
    )
    if spec.grid:
        raise InvalidArgumentError(
            f"tune searches --param; --set {', '.join(spec.grid)} may give one value only"
        )
    spec.metric_description = metric_description(spec)
    return run_experiment(spec, out, address=address, num_cpus=num_cpus, progress=progress)


def resume(
    out: str | os.PathLike[str],
    *,
    address: str | None = None,
    num_cpus: int | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """Continue the experiment in a sweep folder (after its driver was killed or stopped).

    Finished trials are kept as they are (never run again); unfinished ones continue
    from their last checkpoints.

    Raises:
        RunFolderError: The folder holds no sweep, or is in use.
    """
    return run_experiment(
        None, out, resume=True, address=address, num_cpus=num_cpus, progress=progress
    )
