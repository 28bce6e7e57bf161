"""Learning figures: error against the exact answer and return per episode, over seeds.

A learner's run is read as a :class:`LearningCurves`: the return of every episode
and, where the model is known, the error against the exact answer at checkpoints.
:func:`learning_curves` reads one from a learner result (or a mapping with the same
fields). Several runs of one algorithm (one per seed) are drawn as their mean with a
bootstrap confidence band; several algorithms share one figure.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.validation import as_generator, check_count, check_number

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "LearningCurves",
    "bootstrap_ci",
    "draw_mean_with_band",
    "learning_curves",
    "learning_figure",
    "moving_average",
]

#: Names under which learner results keep their per-episode returns.
_RETURN_FIELDS = ("episode_returns", "returns")
#: Names of the checkpoint episodes of the error curve.
_CHECKPOINT_FIELDS = ("checkpoints", "error_episodes", "eval_episodes", "checkpoint_episodes")
#: Names of the error curve, with the label of its axis.
_ERROR_FIELDS = (
    ("error_rms", "RMS error of the estimate vs the exact answer"),
    ("rms_error", "RMS error of the estimate vs the exact answer"),
    ("errors", "error of the estimate vs the exact answer"),
    ("error_curve", "error of the estimate vs the exact answer"),
    ("error_max", "max error of the estimate vs the exact answer"),
    ("max_error", "max error of the estimate vs the exact answer"),
)


#: Also looked up inside a nested ``error`` object or mapping.
_ERROR_FIELDS_NESTED = (
    *_ERROR_FIELDS,
    ("rms", "RMS error vs the exact answer"),
    ("max", "max error vs the exact answer"),
)


@dataclass(frozen=True)
class LearningCurves:
    """The curves of one learning run.

    Attributes:
        episode_returns: (E,) return of each episode.
        checkpoints: (C,) episode counts at which the error was measured, or None.
        error: (C,) error against the exact answer at each checkpoint, or None.
        error_label: What the error measures (axis label).
    """

    episode_returns: NDArray[np.float64] | None
    checkpoints: NDArray[np.float64] | None = None
    error: NDArray[np.float64] | None = None
    error_label: str = "error vs the exact answer"


def _field(obj: Any, name: str) -> Any:
    if isinstance(obj, Mapping):
        return obj.get(name)
    return getattr(obj, name, None)


def _array(x: Any, what: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidArgumentError(
            f"{what} must be an array of numbers; got {type(x).__name__}"
        ) from None
    if arr.ndim != 1:
        raise InvalidArgumentError(f"{what} must be one-dimensional; got shape {arr.shape}")
    return arr


def learning_curves(result: Any) -> LearningCurves:
    """Read the curves of one run from a learner result or a mapping.

    The result gives its per-episode returns as ``episode_returns`` and, where the
    model is known, an error curve (``error_rms``, ``errors``, ``error_max``, ...,
    or an ``error`` mapping/object holding such an array) with the episode count of
    each point (``checkpoints``, ``error_episodes``, ...; default: evenly spaced
    over the episodes).

    Raises:
        InvalidArgumentError: If the result has neither returns nor an error curve.
    """
    if isinstance(result, LearningCurves):
        return result
    rets = next((_field(result, n) for n in _RETURN_FIELDS if _field(result, n) is not None), None)
    returns = _array(rets, "episode_returns") if rets is not None else None
    error = None
    label = "error vs the exact answer"
    holders = [result]
    nested = _field(result, "error")
    if nested is not None and not isinstance(nested, (int, float)):
        if isinstance(nested, (Sequence, np.ndarray)) and not isinstance(nested, str):
            error = _array(nested, "error")
        else:
            holders.append(nested)
    if error is None:
        for holder in holders:
            for name, lab in _ERROR_FIELDS_NESTED:
                val = _field(holder, name)
                if val is not None and np.ndim(val) == 1 and len(val) > 0:
                    error, label = _array(val, name), lab
                    break
            if error is not None:
                break
    checkpoints = None
    if error is not None:
        cp = next(
            (_field(h, n) for h in holders for n in _CHECKPOINT_FIELDS if _field(h, n) is not None),
            None,
        )
        if cp is not None:
            checkpoints = _array(cp, "checkpoints")
        else:
            total = len(returns) if returns is not None else len(error)
            checkpoints = (
                np.linspace(total / len(error), total, len(error)) if len(error) else error
            )
        if checkpoints.shape != error.shape:
            raise InvalidArgumentError(
                f"the error curve has {len(error)} points but {len(checkpoints)} checkpoints"
            )
    target = _field(result, "error_target")
    if error is not None and isinstance(target, str):  # what the error is measured against
        label = label.replace("the exact answer", f"exact {target}")
    if returns is None and error is None:
        raise InvalidArgumentError(
            f"a learning figure needs per-episode returns (episode_returns) or an error curve "
            f"(error_rms, errors, ... with checkpoints); {type(result).__name__} has neither"
        )
    return LearningCurves(returns, checkpoints, error, label)


def bootstrap_ci(
    samples: ArrayLike,
    confidence: float = 0.95,
    n_resamples: int = 1000,
    seed: int | np.random.Generator | None = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Percentile-bootstrap confidence interval of the mean over runs, per point.

    For samples x_1..x_n (one row per run), draw n rows with replacement
    ``n_resamples`` times, take the mean of each draw, and return the
    ((1 - confidence) / 2, (1 + confidence) / 2) quantiles of those means.

    Args:
        samples: (n_runs, n_points) array.
        confidence: Coverage of the interval, in (0, 1).
        n_resamples: Number of bootstrap draws.
        seed: Seed or generator of the draws.

    Returns:
        (low, high), each of shape (n_points,).
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 1:
        raise InvalidArgumentError(f"samples must be (n_runs, n_points); got shape {x.shape}")
    confidence = check_number(
        confidence, "confidence", low=0.0, high=1.0, low_open=True, high_open=True
    )
    n_resamples = check_count(n_resamples, "n_resamples")
    n = x.shape[0]
    rng = as_generator(seed)
    # Each draw is a multinomial count of how often every run was picked, so the means
    # of all draws are one (n_resamples, n) @ (n, n_points) product.
    counts = rng.multinomial(n, np.full(n, 1.0 / n), size=n_resamples).astype(np.float64)
    means = counts @ np.nan_to_num(x) / n
    lo, hi = np.quantile(means, [(1 - confidence) / 2, (1 + confidence) / 2], axis=0)
    return lo, hi


def moving_average(x: ArrayLike, window: int) -> NDArray[np.float64]:
    """Trailing mean over the last ``window`` points (fewer at the start)."""
    arr = np.asarray(x, dtype=np.float64)
    if window <= 1 or arr.size == 0:
        return arr
    c = np.cumsum(np.insert(arr, 0, 0.0, axis=-1), axis=-1)
    idx = np.arange(1, arr.shape[-1] + 1)
    lo = np.maximum(idx - window, 0)
    return np.asarray((c[..., idx] - c[..., lo]) / (idx - lo))


def draw_mean_with_band(
    ax: Axes,
    x: ArrayLike,
    runs: ArrayLike,
    *,
    label: str,
    color: Any = None,
    confidence: float = 0.95,
    seed: int = 0,
) -> None:
    """The mean over runs as a line, with its bootstrap confidence band when runs > 1."""
    xs = np.asarray(x, dtype=np.float64)
    ys = np.atleast_2d(np.asarray(runs, dtype=np.float64))
    mean = ys.mean(axis=0)
    (line,) = ax.plot(xs, mean, label=label, color=color, lw=1.6)
    if ys.shape[0] > 1:
        lo, hi = bootstrap_ci(ys, confidence=confidence, seed=seed)
        ax.fill_between(xs, lo, hi, color=line.get_color(), alpha=0.2, lw=0)


def _as_groups(results: Any) -> dict[str, list[LearningCurves]]:
    if isinstance(results, Mapping) and not _looks_like_result(results):
        groups = {}
        for lab, runs in results.items():
            items = runs if isinstance(runs, (list, tuple)) else [runs]
            if not items:
                raise InvalidArgumentError(f"no runs given for {lab!r}")
            groups[str(lab)] = [learning_curves(r) for r in items]
        if not groups:
            raise InvalidArgumentError("a learning figure needs at least one result")
        return groups
    if isinstance(results, (list, tuple)):
        if not results:
            raise InvalidArgumentError("a learning figure needs at least one result")
        return {"runs": [learning_curves(r) for r in results]}
    return {_result_name(results): [learning_curves(results)]}


def _looks_like_result(m: Mapping[Any, Any]) -> bool:
    return any(k in m for k in _RETURN_FIELDS) or any(k in m for k, _ in _ERROR_FIELDS)


def _result_name(result: Any) -> str:
    for name in ("algorithm", "name", "algo"):
        val = _field(result, name)
        if isinstance(val, str):
            return val
    return "run"


def _stack(arrays: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Runs of possibly different lengths cut to the shortest, as one (n, m) array."""
    m = min(len(a) for a in arrays)
    return np.stack([a[:m] for a in arrays])


def learning_figure(
    results: Any,
    *,
    title: str | None = None,
    smooth: int | None = None,
    confidence: float = 0.95,
) -> Figure:
    """Error against the exact answer and return per episode, for one or more algorithms.

    Args:
        results: One learner result, a list of results (seeds of one algorithm), or a
            mapping ``{label: [result per seed]}`` (several algorithms on one figure).
        title: Figure title.
        smooth: Window of the moving average of returns (default: about 1/25 of the
            episodes).
        confidence: Coverage of the bootstrap band around the mean over seeds.

    Raises:
        InvalidArgumentError: If a result has neither returns nor an error curve.
    """
    from policylab.plot._common import new_figure

    groups = _as_groups(results)
    has_err = any(c.error is not None for runs in groups.values() for c in runs)
    has_ret = any(c.episode_returns is not None for runs in groups.values() for c in runs)
    n = int(has_err) + int(has_ret)
    fig = new_figure(6.5 * n, 4.2)
    axes = fig.subplots(1, n, squeeze=False)[0]
    n_seeds = max(len(r) for r in groups.values())
    band = f"mean over seeds with {confidence:.0%} bootstrap band" if n_seeds > 1 else ""
    i = 0
    if has_err:
        ax = axes[i]
        label = "error vs the exact answer"
        for k, (lab, runs) in enumerate(groups.items()):
            with_err = [c for c in runs if c.error is not None and c.checkpoints is not None]
            if not with_err:
                continue
            label = with_err[0].error_label
            ys = _stack([c.error for c in with_err])  # type: ignore[misc]
            xs = with_err[0].checkpoints[: ys.shape[1]]  # type: ignore[index]
            draw_mean_with_band(
                ax,
                xs,
                ys,
                label=f"{lab} (n={len(with_err)})" if n_seeds > 1 else lab,
                color=f"C{k}",
                confidence=confidence,
                seed=k,
            )
        ax.set_xlabel("episodes")
        ax.set_ylabel(label)
        ax.set_title(
            "error against the exact answer" + (f"\n({band})" if band else ""), fontsize=10
        )
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, frameon=False)
        i += 1
    if has_ret:
        ax = axes[i]
        lengths = [
            len(c.episode_returns)
            for runs in groups.values()
            for c in runs
            if c.episode_returns is not None
        ]
        window = smooth if smooth is not None else max(1, min(lengths) // 25)
        for k, (lab, runs) in enumerate(groups.items()):
            rets = [c.episode_returns for c in runs if c.episode_returns is not None]
            if not rets:
                continue
            ys = moving_average(_stack(rets), window)
            xs = np.arange(1, ys.shape[1] + 1)
            draw_mean_with_band(
                ax,
                xs,
                ys,
                label=f"{lab} (n={len(rets)})" if n_seeds > 1 else lab,
                color=f"C{k}",
                confidence=confidence,
                seed=k,
            )
        ax.set_xlabel("episode")
        ax.set_ylabel(
            "return per episode" + (f" (moving average of {window})" if window > 1 else "")
        )
        ax.set_title("return per episode" + (f"\n({band})" if band else ""), fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, frameon=False)
    fig.suptitle(title if title is not None else "Learning curves")
    return fig
