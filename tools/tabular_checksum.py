"""A checksum over every tabular learner's results, to compare two versions of the code.

Runs all thirteen learners (TD and Monte Carlo) with fixed seeds on cliff walking and
FrozenLake 4x4 (the compiled path), eight of them on Gymnasium's FrozenLake (the general
path), and ``seed_study`` of six, and hashes every result's Q, V, policy, counts,
returns, lengths, first actions, truncations, error curves and steps. A change that
must keep the random stream and the results (a faster kernel, a refactoring) must print
the same checksum before and after::

    PYTHONPATH=/tmp/before/src .venv/bin/python tools/tabular_checksum.py
    .venv/bin/python tools/tabular_checksum.py          # -v: one line per run

(``/tmp/before`` an older commit, e.g. ``git archive COMMIT | tar -x -C /tmp/before``.)
"""

from __future__ import annotations

import hashlib
import sys
import warnings
from typing import Any

import gymnasium as gym
import numpy as np

import policylab as pl
from policylab import tabular

FIELDS = (
    "q", "v", "policy", "counts", "episode_returns", "episode_lengths", "first_actions",
    "error_max", "error_rms", "optimal_actions", "truncated",
)  # fmt: skip
CONTROL: dict[str, dict[str, Any]] = {
    "sarsa": {},
    "q_learning": {},
    "expected_sarsa": {},
    "double_q_learning": {},
    "dyna_q": {"planning_steps": 5},
    "n_step_sarsa": {"n": 3},
    "sarsa_lambda": {"lam": 0.8, "trace": "replacing"},
    "mc_control": {},
    "mc_off_policy": {},
}
PREDICTION: dict[str, dict[str, Any]] = {
    "td0": {},
    "n_step_td": {"n": 3},
    "td_lambda": {"lam": 0.7},
    "mc_prediction": {},
}


def main(verbose: bool) -> str:
    """Run everything; return the checksum (16 hex digits)."""
    warnings.simplefilter("ignore")
    total = hashlib.sha256()

    def add(name: str, res: Any) -> None:
        h = hashlib.sha256()
        for field in FIELDS:
            x = getattr(res, field, None)
            if x is not None:
                h.update(np.asarray(x, dtype=float).tobytes())
        h.update(str(res.steps).encode())
        total.update(h.digest())
        if verbose:
            print(name, h.hexdigest()[:12], res.steps)

    cliff = pl.problems.cliff_walking()
    lake = pl.FiniteMDP.from_gymnasium(gym.make("FrozenLake-v1", map_name="4x4"), gamma=0.95)
    for pname, problem in (("cliff", cliff), ("lake", lake)):
        for name, kw in CONTROL.items():
            add(f"{name}/{pname}", getattr(tabular, name)(problem, episodes=300, seed=3, **kw))
        uniform = pl.Policy.uniform(problem)
        for name, kw in PREDICTION.items():
            res = getattr(tabular, name)(problem, episodes=300, seed=3, policy=uniform, **kw)
            add(f"{name}/{pname}", res)
    env = gym.make("FrozenLake-v1", map_name="4x4")
    for name in ("sarsa", "q_learning", "n_step_sarsa", "sarsa_lambda", "dyna_q",
                 "expected_sarsa", "double_q_learning", "mc_control"):  # fmt: skip
        add(f"{name}/gym", getattr(tabular, name)(env, episodes=100, seed=5))
    for name in ("sarsa", "q_learning", "sarsa_lambda", "n_step_td", "td_lambda", "mc_control"):
        kw = {"policy": pl.Policy.uniform(cliff)} if name in ("n_step_td", "td_lambda") else {}
        study = tabular.seed_study(name, cliff, 6, seed=1, episodes=100, **kw)
        digest = hashlib.sha256(np.asarray(study.returns).tobytes()).hexdigest()[:12]
        total.update(digest.encode())
        if verbose:
            print("seed_study", name, digest)
    return total.hexdigest()[:16]


if __name__ == "__main__":
    print("CHECKSUM", main("-v" in sys.argv[1:]))
