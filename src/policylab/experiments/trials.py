"""What one trial computes: a tabular configuration over its seeds, or deep runs in segments.

Two kinds of trial, chosen by the algorithm:

- **Tabular** (:func:`run_tabular`): one trial runs *all seeds* of a configuration in one
  call (``seed_study``: the compiled kernels run the seeds together), because a
  tabular run takes milliseconds and a Ray trial costs far more than that. Run r is
  exactly ``policylab learn ALGO PROBLEM --seed seeds[r]``; each seed's final table is
  scored against the exact answer of the planning layer (q* for control, v_pi for
  prediction) where the model is known.
- **Deep** (:func:`run_deep`): the seeds of a trial train in lockstep *segments* of
  ``checkpoint_every`` steps. Every segment starts from the checkpoint the previous one
  saved (``policylab train --resume``'s path), whether or not the trial was interrupted:
  so a trial retried from its last checkpoint after its worker died follows exactly the
  path of one that never failed, and ends with the same result. (Each segment restarts
  the episodes in progress, as ``--resume`` does; a sweep's deep run therefore differs
  from one uninterrupted ``policylab train`` run by those restarts, and from nothing else.)

The functions here take plain data and import no Ray; :mod:`policylab.experiments.ray_trials`
wraps them as Ray Tune function trainables.
"""

from __future__ import annotations

import itertools
import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.experiments.problems import (
    deep_fields,
    finite_problem,
    ground_truth,
    named_policy,
    reachable_states,
)
from policylab.experiments.spec import ExperimentSpec
from policylab.runs import CHECKPOINT, RUN_JSON, atomic_write_bytes

__all__ = [
    "CURVE_JSON",
    "TABLES_NPZ",
    "last_share_mean",
    "run_deep",
    "run_tabular",
    "tabular_kwargs",
]

TABLES_NPZ = "tables.npz"
"""A tabular trial's learned tables and returns, per seed."""
CURVE_JSON = "curve.json"
"""Per-seed learning curve of a deep run (steps, recent return), kept beside its checkpoint."""

#: Step limit of one tabular episode (``policylab learn``'s ``--max-steps`` default).
MAX_STEPS = 10_000
#: Points of a tabular learning curve in sweep.json (bins of episodes).
CURVE_POINTS = 50


def last_share_mean(returns: np.ndarray, share: float = 0.1) -> float:
    """Mean of the last ``share`` of a run's episode returns (at least one episode)."""
    n = max(1, math.ceil(len(returns) * share))
    return float(np.mean(returns[-n:]))


def tabular_kwargs(spec: ExperimentSpec, config: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    """(problem, learner keyword arguments) of one tabular configuration, as ``learn`` builds them.

    The discount ``gamma`` goes into the problem (``policylab learn --gamma``), flags
    become their learner value, schedules are parsed, a prediction's policy is built.
    """
    from policylab.tabular.registry import algorithm
    from policylab.tabular.schedules import Schedule

    alg = algorithm(spec.algorithm)
    settings = spec.settings(config)
    mdp = finite_problem(spec.problem, settings.pop("gamma", None))
    kinds = {o.param: o for o in alg.options}
    kwargs: dict[str, Any] = {
        "episodes": int(settings.pop("episodes", alg.default_episodes)),
        "max_steps": int(settings.pop("max_steps", MAX_STEPS)),
    }
    if alg.kind == "prediction":
        kwargs["policy"] = named_policy(spec.problem, mdp, settings.pop("policy", None))
    for param, value in settings.items():
        opt = kinds.get(param)
        if opt is None:
            raise InvalidArgumentError(f"{spec.algorithm} has no option {param!r}")
        if opt.kind == "flag":
            if value:
                kwargs[param] = opt.value_if_set
        elif opt.kind == "schedule":
            kwargs[param] = Schedule.parse(str(value))
        elif opt.kind == "policy":
            kwargs[param] = named_policy(spec.problem, mdp, value)
        else:
            kwargs[param] = value
    return mdp, kwargs


def _seed_runs(
    name: str, mdp: Any, seeds: list[int], kwargs: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(returns (R, E), q (R, S, A), v (R, S)) of every seed, all seeds in one call."""
    from policylab.tabular import run_seeds, seed_study
    from policylab.tabular.registry import algorithm

    kw = dict(kwargs)
    episodes = kw.pop("episodes")
    policy = kw.pop("policy", None)
    try:
        runs = seed_study(name, mdp, seeds=seeds, episodes=episodes, policy=policy, **kw)
    except InvalidArgumentError as e:
        if "unknown TD algorithm" not in str(e):
            raise
    else:
        return runs.returns, runs.q, runs.v
    # learners outside seed_study (Monte Carlo): the seeds still run at once, on threads
    if policy is not None:
        kw["policy"] = policy
    results = run_seeds(algorithm(name).learner, mdp, seeds, episodes=episodes, **kw)
    v = [r.v if r.v is not None else np.zeros(len(r.states)) for r in results]
    return (
        np.stack([r.episode_returns for r in results]),
        np.stack([r.q for r in results]),
        np.stack(v),
    )


def run_tabular(
    spec: ExperimentSpec, config: dict[str, Any], seeds: list[int], folder: Path | None = None
) -> dict[str, Any]:
    """One tabular configuration over ``seeds``: the trial's result (JSON-ready).

    With ``folder``, the learned tables and every episode's return are kept there in
    ``tables.npz`` (arrays ``seeds`` (R,), ``q`` (R, S, A), ``v`` (R, S), ``returns``
    (R, episodes)), written atomically.

    Returns:
        ``{"score": mean over seeds, "per_seed": [{"seed", "metrics", "curve"}, ...]}``.
        Each seed's metrics: ``return_last10`` (mean return of the last 10% of episodes),
        ``error_max``, ``error_rms``, ``optimal_actions`` (against the exact answer, over
        all states, as ``policylab learn`` reports them), ``reachable_error_rms`` (the RMS
        error over the states reachable from the start) and ``score`` (the experiment's
        metric, see :func:`metric_description`).
    """
    mdp, kwargs = tabular_kwargs(spec, config)
    returns, q, v = _seed_runs(spec.algorithm, mdp, seeds, kwargs)
    if folder is not None:
        import io

        buf = io.BytesIO()
        np.savez_compressed(buf, seeds=np.asarray(seeds), q=q, v=v, returns=returns)
        atomic_write_bytes(folder / TABLES_NPZ, buf.getvalue())
    truth = ground_truth(spec.algorithm, mdp, kwargs.get("policy"))
    reachable = reachable_states(mdp)
    episodes = returns.shape[1]
    edges = np.unique(np.linspace(0, episodes, min(CURVE_POINTS, episodes) + 1).round().astype(int))
    per_seed: list[dict[str, Any]] = []
    scores: list[float] = []
    for r, seed in enumerate(seeds):
        e_max, e_rms, share = truth.errors(q[r], v[r])  # over all states, as `learn` gives it
        _, reach_rms, _ = truth.errors(q[r], v[r], seen=reachable)
        metrics = {
            "return_last10": last_share_mean(returns[r]),
            "error_max": e_max,
            "error_rms": e_rms,
            "optimal_actions": share,
            "reachable_error_rms": reach_rms,
        }
        metrics["score"] = -reach_rms if spec.command == "tune" else metrics["return_last10"]
        curve = {
            "x": [int(b) for b in edges[1:]],
            "y": [float(returns[r, a:b].mean()) for a, b in itertools.pairwise(edges)],
            "x_label": "episode",
            "y_label": "mean return of the episodes up to x since the previous point",
        }
        per_seed.append({"seed": int(seed), "metrics": _finite(metrics), "curve": curve})
        scores.append(metrics["score"])
    return {
        "score": float(np.mean(scores)),
        "per_seed": per_seed,
    }


def metric_description(spec: ExperimentSpec) -> str:
    """What ``score`` means for this experiment."""
    if spec.family == "deep":
        return "mean return of the last 100 training episodes"
    truth = ground_truth(
        spec.algorithm, finite_problem(spec.problem, spec.fixed.get("gamma")), None
    )
    if spec.command == "tune":
        return (
            f"minus the RMS error of the learned values against the exact {truth.target}, "
            "over the states reachable from the start"
        )
    return "mean return of the last 10% of episodes"


def _finite(d: dict[str, float]) -> dict[str, float | None]:
    """Metrics as JSON-ready numbers (NaN as null)."""
    return {k: (float(x) if math.isfinite(x) else None) for k, x in d.items()}


# ---------------------------------------------------------------------------- deep
def run_deep(
    spec: ExperimentSpec,
    config: dict[str, Any],
    seeds: list[int],
    folder: Path,
    on_segment: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Deep runs of one configuration, one per seed, in lockstep checkpointed segments.

    Seed k's run folder is ``folder/seed-k``; every segment of ``checkpoint_every`` steps
    continues from the checkpoint the previous segment saved there. ``on_segment`` gets
    the result so far after each segment (the caller reports it and its checkpoint).

    Returns:
        ``{"score", "per_seed": [{"seed", "metrics", "curve"}]}``; metrics per seed are
        ``score`` (mean return of the last 100 training episodes), ``steps``, ``episodes``.
    """
    from policylab.deep.common.config import config_from_dict
    from policylab.deep.io import resume
    from policylab.deep.zoo import ALGORITHMS

    cls = ALGORITHMS[spec.algorithm]
    dirs = [folder / f"seed-{s}" for s in seeds]
    done = [False] * len(seeds)
    state: list[dict[str, Any]] = [{} for _ in seeds]
    while not all(done):
        for i, seed in enumerate(seeds):
            if done[i]:
                continue
            fields = deep_fields(spec, config, seed)
            total = int(fields.pop("steps"))
            cfg = config_from_dict(cls.config_class, fields)
            every = cfg.checkpoint_every or max(1, total // 10)
            run_dir = dirs[i]
            curve_path = run_dir / CURVE_JSON
            if (run_dir / CHECKPOINT).is_file():
                agent = resume(run_dir)
                curve = json.loads(curve_path.read_text()) if curve_path.is_file() else _curve()
            else:  # a fresh start (a worker that died before the first checkpoint kept nothing)
                shutil.rmtree(run_dir, ignore_errors=True)
                agent = cls(spec.problem, config=cfg)
                curve = _curve()
            boundary = min(total, (agent.num_timesteps // every + 1) * every)
            agent.learn(total, callback=_until(boundary), run_dir=run_dir)
            recent = agent.recent_mean_return()
            curve["x"].append(int(agent.num_timesteps))
            curve["y"].append(None if recent is None else float(recent))
            atomic_write_bytes(curve_path, json.dumps(curve).encode())
            done[i] = agent.num_timesteps >= total
            state[i] = {
                "seed": int(seed),
                "metrics": {
                    "score": None if recent is None else float(recent),
                    "steps": int(agent.num_timesteps),
                    "episodes": int(agent.episodes),
                },
                "curve": curve,
            }
        result = _deep_result(state)
        result["finished"] = all(done)
        if on_segment is not None:
            on_segment(result)
    return result


def _until(step: int) -> Callable[[Any, dict[str, float]], bool]:
    """A training callback that stops the segment once the agent has reached ``step``."""

    def keep_going(agent: Any, metrics: dict[str, float]) -> bool:
        return bool(agent.num_timesteps < step)

    return keep_going


def _curve() -> dict[str, Any]:
    return {"x": [], "y": [], "x_label": "step", "y_label": "mean return of the last 100 episodes"}


def _deep_result(state: list[dict[str, Any]]) -> dict[str, Any]:
    scores = [s["metrics"]["score"] for s in state if s["metrics"]["score"] is not None]
    return {
        "score": float(np.mean(scores)) if scores else float("-inf"),
        "per_seed": [dict(s) for s in state],
    }


#: Files of a deep run folder that a trial's Tune checkpoint carries.
CHECKPOINT_FILES = (CHECKPOINT, RUN_JSON, CURVE_JSON)
