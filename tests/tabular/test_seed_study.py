"""seed_study: many seeds in one compiled call, each run exactly the learner alone.

Run r of ``seed_study(name, problem, seeds=[...])`` must be ``learner(problem,
seed=seeds[r])`` bit for bit, whatever the number of threads the parallel loop runs on.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

import policylab as pl
from policylab import tabular as tab
from policylab.exceptions import InvalidArgumentError

SEEDS = [3, 11, 2**40 + 5]


def _problem(spec: tab.AlgorithmSpec) -> pl.FiniteMDP:
    return pl.problems.random_walk() if spec.kind == "prediction" else pl.problems.cliff_walking()


def _same(study: tab.SeedRuns, r: int, alone: tab.LearnResult) -> None:
    np.testing.assert_array_equal(study.returns[r], alone.episode_returns)
    np.testing.assert_array_equal(study.q[r], alone.q)
    np.testing.assert_array_equal(study.v[r], alone.v)
    if alone.episode_lengths is not None:
        np.testing.assert_array_equal(study.lengths[r], alone.episode_lengths)


@pytest.mark.parametrize("spec", tab.list_algorithms(), ids=lambda s: s.name)
def test_every_algorithm_runs_each_seed_exactly_as_the_learner_alone(spec):
    mdp = _problem(spec)
    study = tab.seed_study(spec.name, mdp, SEEDS, episodes=15)
    assert study.seeds == len(SEEDS) and study.returns.shape == (len(SEEDS), 15)
    for r, s in enumerate(SEEDS):
        _same(study, r, spec.learner(mdp, episodes=15, seed=s))
    assert len({tuple(row) for row in study.returns}) > 1  # the seeds give different runs


@pytest.mark.parametrize("name", ["sarsa", "double-q-learning", "sarsa-lambda", "n-step-td"])
def test_the_numbers_do_not_depend_on_the_number_of_threads(name):
    mdp = _problem(tab.algorithm(name))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = tab.seed_study(name, mdp, 8, seed=4, episodes=25, alpha=0.3)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = tab.seed_study(name, mdp, 8, seed=4, episodes=25, alpha=0.3)
    finally:
        numba.set_num_threads(before)
    by_workers = tab.seed_study(name, mdp, 8, seed=4, episodes=25, alpha=0.3, workers=1)
    for other in (two, by_workers):
        np.testing.assert_array_equal(one.returns, other.returns)
        np.testing.assert_array_equal(one.lengths, other.lengths)
        np.testing.assert_array_equal(one.q, other.q)
        np.testing.assert_array_equal(one.v, other.v)
        assert one.steps == other.steps
    assert numba.get_num_threads() == before


def test_a_count_of_seeds_draws_them_from_seed_and_a_list_gives_them_as_is():
    mdp = pl.problems.cliff_walking()
    drawn = np.random.default_rng(5).integers(2**63 - 1, size=3)
    by_count = tab.seed_study("q-learning", mdp, 3, seed=5, episodes=10)
    by_list = tab.seed_study("q-learning", mdp, [int(s) for s in drawn], episodes=10)
    np.testing.assert_array_equal(by_count.returns, by_list.returns)
    np.testing.assert_array_equal(by_count.q, by_list.q)


@pytest.mark.parametrize(
    ("seeds", "match"),
    [([], "must not be empty"), ([1, -2], r"seeds\[1\]"), ("12", "sequence"), ([1.5], "integer")],
)
def test_bad_seeds_are_refused_by_name(seeds, match):
    with pytest.raises(InvalidArgumentError, match=match):
        tab.seed_study("sarsa", pl.problems.cliff_walking(), seeds, episodes=2)
