"""The order in which the test files start: two workers end together and compile once.

``make test`` runs ``pytest -n 2 --dist loadfile``: each file runs whole on one worker,
and pytest-xdist hands the files out in the order collected (``--no-loadscope-reorder``
in the pytest settings keeps it from reordering them by their number of tests):

1. The documentation site first. Its build runs the code of every page, which compiles
   nearly every numba kernel of the package into numba's on-disk cache (on a fresh
   machine that is most of the build's three minutes).
2. Meanwhile the other worker runs the files that compile no kernel (``tests/deep``:
   torch only), so that the two workers do not compile the same kernels side by side.
3. Then the slowest files, longest first, so that the long files run side by side and
   the many short ones fill the gaps at the end, instead of one long file running alone
   while the other worker idles.

The order changes nothing else: every file still runs whole and in its own order.
"""

from __future__ import annotations

import pytest

#: The file that runs first (see the module's docstring).
FIRST = "tests/docs/test_site.py"

#: The folder of the files that compile no numba kernel; they run second.
NO_KERNELS = "tests/deep/"

#: The slowest of the other files, slowest first (seconds each in a cold-cache run of
#: ``make test`` on 2 AMD EPYC cores, December 2026, in brackets); the files not named
#: keep their collection order after these. A file missing here or gone from the suite
#: changes only the order.
SLOWEST_FIRST = (
    "tests/experiments/test_sweep_ray.py",  # (79)
    "tests/tabular/test_blackjack.py",  # (68)
    "tests/docs/test_readme.py",  # (51)
    "tests/games/test_runs.py",  # (35)
    "tests/plot/test_solution_figures.py",  # (32)
    "tests/experiments/test_cluster.py",  # (28)
    "tests/games/test_alphazero_ray.py",  # (23)
    "tests/planning/test_threads.py",  # (19)
    "tests/cli/test_bad_input.py",  # (16)
    "tests/tabular/test_seed_study.py",  # (15)
    "tests/tabular/test_td_equivalence.py",  # (13)
    "tests/cli/test_cli_core.py",  # (13)
    "tests/plot/test_tour_figures.py",  # (12)
    "tests/test_numba_cache.py",  # (11)
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    slow = {path: i for i, path in enumerate(SLOWEST_FIRST)}

    def key(item: pytest.Item) -> tuple[int, int]:
        path = item.nodeid.split("::", 1)[0]
        if path == FIRST:
            return (0, 0)
        if path.startswith(NO_KERNELS):
            return (1, 0)
        return (2, slow.get(path, len(slow)))

    items.sort(key=key)  # stable: each group keeps its collection order
