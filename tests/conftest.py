"""The order in which the test files start: the longest first, so two workers end together.

``make test`` runs ``pytest -n 2 --dist loadfile``: each file runs whole on one worker,
and pytest-xdist hands the files out in the order collected (``--no-loadscope-reorder``
in the pytest settings keeps it from reordering them by their number of tests). Started
longest first, the long files run side by side from the start and the many short ones
fill the gaps at the end, instead of one long file running alone while the other
worker idles. The order changes nothing else: every file still runs whole and in
its own order.
"""

from __future__ import annotations

import pytest

#: The slowest test files, slowest first (``pytest -n 2 --durations=60``, summed per file);
#: the files not named keep their collection order after these. A file missing here or
#: gone from the suite changes only the order.
SLOWEST_FIRST = (
    "tests/docs/test_site.py",
    "tests/cli/test_cli_core.py",
    "tests/tabular/test_td_equivalence.py",
    "tests/games/test_runs.py",
    "tests/experiments/test_sweep_ray.py",
    "tests/experiments/test_sweep_cli.py",
    "tests/tabular/test_blind_spots.py",
    "tests/tabular/test_registry.py",
    "tests/docs/test_readme.py",
    "tests/tabular/test_seed_study.py",
    "tests/deep/test_ppo.py",
    "tests/games/test_alphazero_ray.py",
    "tests/plot/test_solution_figures.py",
    "tests/deep/test_sac_td3.py",
    "tests/deep/test_dqn.py",
    "tests/experiments/test_cluster.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {path: i for i, path in enumerate(SLOWEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))
