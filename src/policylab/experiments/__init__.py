"""Many trials at once on Ray Tune: seed sweeps, hyperparameter tuning, resume.

``sweep`` runs an algorithm for every configuration of a grid and every seed; ``tune``
searches hyperparameters (Optuna's TPE sampler through Tune's ``OptunaSearch``, with
early stopping); ``resume`` continues either after its driver was killed. Each writes a
sweep folder whose ``sweep.json`` lists every trial (configuration, seed, status,
metrics, learning curve) and the statistics per configuration. Ray is imported only
when one of these runs, so ``import policylab`` stays fast.

Example:
    >>> import policylab.experiments as ex
    >>> doc = ex.sweep("q-learning", "CliffWalking-v1", seeds=8, out="sweeps/q",
    ...                options={"episodes": 500}, grid={"alpha": [0.1, 0.5]})  # doctest: +SKIP
    >>> sorted(doc["statistics"])  # doctest: +SKIP
    ['alpha=0.1', 'alpha=0.5']
"""

from policylab.experiments.runner import SWEEP_JSON, resume, run_experiment, sweep, tune
from policylab.experiments.spec import (
    ExperimentSpec,
    build_spec,
    config_label,
    parse_distribution,
    parse_option_tokens,
    parse_set,
)

__all__ = [
    "SWEEP_JSON",
    "ExperimentSpec",
    "build_spec",
    "config_label",
    "parse_distribution",
    "parse_option_tokens",
    "parse_set",
    "resume",
    "run_experiment",
    "sweep",
    "tune",
]
