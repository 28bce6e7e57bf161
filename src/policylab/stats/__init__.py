"""Honest statistics over runs and tasks: IQM, optimality gap, stratified bootstrap.

One run proves little: a result over seeds (runs) and problems (tasks) is a score
matrix of shape ``(runs, tasks)``, summarised by aggregates with confidence intervals,
as recommended by Agarwal et al. (2021), "Deep Reinforcement Learning at the Edge of
the Statistical Precipice" (NeurIPS), and computed as its library rliable does::

    import policylab as pl
    scores = [[0.71, 0.40], [0.65, 0.52], [0.80, 0.47]]   # 3 seeds x 2 problems
    pl.stats.iqm(scores)                                   # interquartile mean
    pl.stats.bootstrap_ci(scores, pl.stats.iqm, reps=2000, seed=0)   # (low, high)
    pl.stats.summarize(scores)      # {"iqm": {"value", "low", "high"}, "mean": ..., ...}

Pure NumPy; the bootstrap is vectorised over resamples. :func:`read_sweep` and
:func:`score_matrices` read the folders of ``policylab sweep`` and ``policylab tune``.
"""

from policylab.stats.aggregates import (
    iqm,
    mean,
    median,
    optimality_gap,
    performance_profile,
    probability_of_improvement,
)
from policylab.stats.bootstrap import (
    DEFAULT_REPS,
    SUMMARY_STATISTICS,
    bootstrap_ci,
    bootstrap_distribution,
    performance_profile_ci,
    probability_of_improvement_ci,
    summarize,
)
from policylab.stats.sweeps import ScoreMatrix, Sweep, SweepRun, read_sweep, score_matrices

__all__ = [
    "DEFAULT_REPS",
    "SUMMARY_STATISTICS",
    "ScoreMatrix",
    "Sweep",
    "SweepRun",
    "bootstrap_ci",
    "bootstrap_distribution",
    "iqm",
    "mean",
    "median",
    "optimality_gap",
    "performance_profile",
    "performance_profile_ci",
    "probability_of_improvement",
    "probability_of_improvement_ci",
    "read_sweep",
    "score_matrices",
    "summarize",
]
