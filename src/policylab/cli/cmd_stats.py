"""``policylab stats DIR [DIR ...]``: honest statistics over the runs of sweeps.

Reads each folder's ``sweep.json`` (written by ``policylab sweep`` or ``policylab
tune``; each folder is one task), groups the finished runs by configuration, and prints
per configuration the IQM, mean, median and optimality gap with stratified bootstrap
confidence intervals, and the probability that the best configuration beats each other
one; it writes the figures (aggregate intervals, performance profiles, learning curves
with bands). ``--json`` prints one object instead of the table.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

__all__ = ["register", "stats_command"]

#: Figures draw at most this many configurations (the best by IQM).
MAX_FIGURE_CONFIGS = 10


def _fmt(v: float, big: bool) -> str:
    return f"{v:,.1f}" if big else f"{v:.3f}"


def _cell(entry: dict[str, float], big: bool) -> str:
    return f"{_fmt(entry['value'], big)} [{_fmt(entry['low'], big)}, {_fmt(entry['high'], big)}]"


def stats_command(
    dirs: Annotated[
        list[Path],
        typer.Argument(
            help="Sweep folders (written by `policylab sweep` or `policylab tune`), one per "
            "task: a configuration found in several is scored over all of them, its runs "
            "matched by seed.",
            show_default=False,
        ),
    ],
    json_out: Annotated[
        bool, typer.Option("--json", help="Print one JSON object instead of the table.")
    ] = False,
    normalize: Annotated[
        str | None,
        typer.Option(
            "--normalize",
            metavar="MIN,MAX",
            help="Map scores to (score - MIN) / (MAX - MIN) before aggregating (for example "
            "the random and the optimal score), so tasks share one scale and the optimality "
            "gap is measured against 1.",
        ),
    ] = None,
    confidence: Annotated[
        float, typer.Option(help="Coverage of the confidence intervals, in (0, 1).")
    ] = 0.95,
    reps: Annotated[int, typer.Option(help="Bootstrap resamples per interval.")] = 2000,
    seed: Annotated[int, typer.Option(help="Seed of the bootstrap resampling.")] = 0,
    threshold: Annotated[
        float,
        typer.Option(help="Target of the optimality gap (on the normalised scale if --normalize)."),
    ] = 1.0,
    metric: Annotated[
        str | None,
        typer.Option(help="The metric to aggregate (default: the one each sweep optimised)."),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            "-o",
            help="Folder for the figures (default: runs/stats/NAME, NAME the folders' names).",
        ),
    ] = None,
    figures: Annotated[
        bool, typer.Option("--figures/--no-figures", help="Write the figures.")
    ] = True,
) -> None:
    """Statistics over runs: IQM, mean, median, optimality gap with bootstrap intervals.

    Following Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge of the
    Statistical Precipice": intervals are percentile intervals of a stratified bootstrap
    (runs resampled within each task), and the interquartile mean (IQM) is the summary
    to read first.
    """
    from policylab.cli.common import console, print_json
    from policylab.stats import (
        probability_of_improvement,
        probability_of_improvement_ci,
        summarize,
    )
    from policylab.stats.sweeps import check_normalize, read_sweep, score_matrices
    from policylab.validation import check_count, check_output_dir, check_seed

    reps = check_count(reps, "--reps")
    check_seed(seed, "--seed")
    bounds = None if normalize is None else check_normalize(normalize, "--normalize")
    target = None
    if figures:
        if out is None:
            out = Path("runs") / "stats" / "+".join(d.resolve().name or "sweep" for d in dirs)
        target = check_output_dir(out, "--out")
    sweeps = [read_sweep(d) for d in dirs]
    matrices, notes = score_matrices(sweeps, metric=metric, normalize=bounds)
    metric_name = metric or sweeps[0].metric
    mode = sweeps[0].mode
    if any(s.mode != mode for s in sweeps):
        notes.append("the sweeps disagree on whether higher scores are better; read as each says")
    sign = -1.0 if mode == "min" else 1.0

    summaries = {
        label: summarize(m.scores, reps=reps, confidence=confidence, seed=seed, threshold=threshold)
        for label, m in matrices.items()
    }
    order = sorted(summaries, key=lambda lab: -sign * summaries[lab]["iqm"]["value"])
    best = order[0]
    improvement: dict[str, dict[str, float]] = {}
    for label in order[1:]:
        x, y = sign * matrices[best].scores, sign * matrices[label].scores
        low, high = probability_of_improvement_ci(x, y, reps=reps, confidence=confidence, seed=seed)
        improvement[label] = {
            "value": probability_of_improvement(x, y),
            "low": low,
            "high": high,
        }
    if mode == "min":
        notes.append(
            f"lower {metric_name!r} is better in these sweeps: the best configuration has the "
            "lowest IQM, while the optimality gap and the profiles read scores as "
            "higher-is-better"
        )
    tasks = list(next(iter(matrices.values())).tasks)
    written: list[str] = []
    if target is not None:
        shown = order[:MAX_FIGURE_CONFIGS]
        if len(order) > len(shown):
            notes.append(
                f"figures show the {len(shown)} best of {len(order)} configurations by IQM"
            )
        written = _write_figures(
            target,
            {lab: matrices[lab] for lab in shown},
            {lab: summaries[lab] for lab in shown},
            sweeps,
            score_label=f"normalised {metric_name}" if bounds else metric_name,
            reps=reps,
            confidence=confidence,
            seed=seed,
        )
    if json_out:
        print_json(
            {
                "dirs": [str(d) for d in dirs],
                "tasks": tasks,
                "algorithms": [s.algorithm for s in sweeps],
                "metric": metric_name,
                "mode": mode,
                "metric_description": (
                    sweeps[0].metric_description if metric_name == sweeps[0].metric else ""
                ),
                "normalize": list(bounds) if bounds else None,
                "confidence": confidence,
                "reps": reps,
                "seed": seed,
                "threshold": threshold,
                "configs": {
                    lab: {
                        "runs": len(matrices[lab].seeds),
                        "tasks": len(matrices[lab].tasks),
                        "seeds": list(matrices[lab].seeds),
                        **summaries[lab],
                        "scores": matrices[lab].scores.tolist(),
                    }
                    for lab in order
                },
                "best": best,
                "probability_of_improvement": {"best": best, "over": improvement},
                "figures": written,
                "notes": notes,
            }
        )
        return
    _print_table(
        sweeps, metric_name, matrices, summaries, order, improvement, confidence, reps, bounds
    )
    for note in notes:
        console.print(f"note: {note}", highlight=False, markup=False)
    for path in written:
        console.print(f"wrote {path}", highlight=False, markup=False)


def _print_table(
    sweeps: list[Any],
    metric: str,
    matrices: dict[str, Any],
    summaries: dict[str, dict[str, dict[str, float]]],
    order: list[str],
    improvement: dict[str, dict[str, float]],
    confidence: float,
    reps: int,
    bounds: tuple[float, float] | None,
) -> None:
    from rich.markup import escape
    from rich.table import Table

    from policylab.cli.common import emit_table

    first = sweeps[0]
    big = any(
        abs(e[k]) >= 1000 for s in summaries.values() for e in s.values() for k in ("value", "low")
    )
    tasks = next(iter(matrices.values())).tasks
    what = f"{first.metric}" + (
        f" ({first.metric_description})" if first.metric_description else ""
    )
    algos = ", ".join(dict.fromkeys(s.algorithm for s in sweeps if s.algorithm))
    table = Table(
        title=escape(
            f"{algos or 'sweep'} on {', '.join(tasks)}: {what}"
            + (f", normalised by {bounds[0]:g}..{bounds[1]:g}" if bounds else "")
        )
    )
    table.add_column("configuration", style="bold")
    table.add_column("runs", justify="right")
    if len(tasks) > 1:
        table.add_column("tasks", justify="right")
    for head in ("IQM", "mean", "median", "optimality gap"):
        table.add_column(head, justify="right")
    if improvement:
        table.add_column(escape(f"P({order[0]} > this)"), justify="right")
    for lab in order:
        row = [lab, str(len(matrices[lab].seeds))]
        if len(tasks) > 1:
            row.append(str(len(tasks)))
        row += [_cell(summaries[lab][k], big) for k in ("iqm", "mean", "median", "optimality_gap")]
        if improvement:
            row.append(_cell(improvement[lab], False) if lab in improvement else "best")
        table.add_row(*(escape(c) for c in row))
    table.caption = escape(
        f"value [low, high]: {confidence:.0%} stratified bootstrap percentile intervals "
        f"({reps:,} resamples); median = median over tasks of each task's mean"
    )
    emit_table(table)


def _write_figures(
    target: Path,
    matrices: dict[str, Any],
    summaries: dict[str, dict[str, dict[str, float]]],
    sweeps: list[Any],
    *,
    score_label: str,
    reps: int,
    confidence: float,
    seed: int,
) -> list[str]:
    from policylab.plot import (
        aggregate_intervals_figure,
        performance_profile_figure,
        run_curves_figure,
        save_figure,
    )

    written = [
        save_figure(
            aggregate_intervals_figure(summaries, score_label=score_label, confidence=confidence),
            target / "aggregates.png",
        ),
        save_figure(
            performance_profile_figure(
                {lab: m.scores for lab, m in matrices.items()},
                reps=reps,
                confidence=confidence,
                seed=seed,
                score_label=score_label,
            ),
            target / "performance_profiles.png",
        ),
    ]
    tasks = next(iter(matrices.values())).tasks
    curves = {task: {lab: m.curves.get(task, []) for lab, m in matrices.items()} for task in tasks}
    if any(runs for by_label in curves.values() for runs in by_label.values()):
        x_label = next(
            (r.x_label for s in sweeps for r in s.runs if r.x_label and r.curve_x.size), "step"
        )
        written.append(
            save_figure(
                run_curves_figure(
                    curves, x_label=x_label, y_label=sweeps[0].metric, confidence=confidence
                ),
                target / "learning_curves.png",
            )
        )
    return [str(p) for p in written]


def register(app: typer.Typer) -> None:
    """Add ``policylab stats`` to the command line."""
    app.command("stats")(stats_command)
