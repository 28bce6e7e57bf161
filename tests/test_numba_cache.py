"""Compiled kernels never run stale code: the cache folder follows every compiled source.

numba's own cache checks only the file of the cached function, so a kernel that inlines
a helper from another file would keep the old helper after an edit. These tests edit a
helper in a copy of the package and run the kernel in fresh processes.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import policylab
from policylab import _numba_cache

PROBE = '''
"""A cached kernel that inlines helpers from two other files (test fixture)."""
import numpy as np
from numba import njit

from policylab.tabular._probe_helper import helper
from policylab.tabular.kernels import epsilon_greedy_prob


@njit(cache=True)
def probe(x):
    q = np.array([1.0, 1.0, 0.0])
    mask = np.ones(3, dtype=np.bool_)
    return helper(x) + epsilon_greedy_prob(q, mask, 0.1, 2)
'''

HELPER = """
from numba import njit


@njit(cache=True)
def helper(x):
    return x + 1.0
"""

RUN = """
import json
import policylab
from policylab import _numba_cache
from policylab.tabular._probe import probe
value = probe(1.0)
print(json.dumps({
    "value": value,
    "hits": sum(probe.stats.cache_hits.values()),
    "misses": sum(probe.stats.cache_misses.values()),
    "package": policylab.__file__,
    "cache_dir": str(_numba_cache.cache_dir()),
}))
"""


def run_probe(root: Path, cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["PYTHONPATH"] = str(root)
    env["NUMBA_CACHE_DIR"] = str(cache)
    out = subprocess.run(
        [sys.executable, "-c", RUN],
        env=env,
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture()
def package_copy(tmp_path: Path) -> Path:
    root = tmp_path / "site"
    src = Path(policylab.__file__).resolve().parent
    shutil.copytree(src, root / "policylab", ignore=shutil.ignore_patterns("__pycache__"))
    (root / "policylab" / "tabular" / "_probe.py").write_text(PROBE)
    (root / "policylab" / "tabular" / "_probe_helper.py").write_text(HELPER)
    return root


def test_editing_a_helper_in_another_file_recompiles_the_kernel(package_copy, tmp_path):
    cache = tmp_path / "numba-cache"
    eps_prob = 0.1 / 3  # epsilon-greedy probability of the non-greedy action 2

    first = run_probe(package_copy, cache)
    assert first["package"].startswith(str(package_copy))
    assert first["value"] == pytest.approx(2.0 + eps_prob)
    assert first["misses"] == 1
    # The user's NUMBA_CACHE_DIR is the parent; nothing is written inside the package.
    assert Path(first["cache_dir"]).parent == cache / "policylab"
    assert not list((package_copy / "policylab").rglob("*.nbi"))

    again = run_probe(package_copy, cache)  # unchanged source: the compiled code is reused
    assert again["value"] == first["value"]
    assert (again["hits"], again["misses"]) == (1, 0)
    assert again["cache_dir"] == first["cache_dir"]

    # Edit the helpers only, never the file of the cached kernel.
    helper = package_copy / "policylab" / "tabular" / "_probe_helper.py"
    helper.write_text(HELPER.replace("x + 1.0", "x + 10.0"))
    kernels = package_copy / "policylab" / "tabular" / "kernels.py"
    kernels.write_text(
        kernels.read_text()
        + textwrap.dedent(
            """

            _old_epsilon_greedy_prob = epsilon_greedy_prob


            @nb.njit(cache=True)
            def epsilon_greedy_prob(q_row, mask_row, epsilon, action):
                return 100.0 + _old_epsilon_greedy_prob(q_row, mask_row, epsilon, action)
            """
        )
    )
    edited = run_probe(package_copy, cache)
    assert edited["value"] == pytest.approx(11.0 + 100.0 + eps_prob)
    assert edited["misses"] == 1
    assert edited["cache_dir"] != first["cache_dir"]


def test_the_key_follows_compiled_sources_and_the_version_only(tmp_path):
    key = _numba_cache.source_key()
    assert key.startswith(f"{policylab.__version__}-")
    assert key == _numba_cache.source_key()  # stable
    package = Path(policylab.__file__).resolve().parent
    sources = _numba_cache._compiled_sources()
    for name in ("tabular/kernels.py", "tabular/td_kernels.py", "planning/_kernels.py"):
        assert package / name in sources
    assert package / "__init__.py" in sources  # the version
    # The command line is not compiled code: editing it does not recompile kernels.
    assert not any(p.relative_to(package).parts[0] == "cli" for p in sources)


def test_old_cache_folders_are_pruned(tmp_path):
    parent = tmp_path / "policylab"
    keep = parent / "current"
    keep.mkdir(parents=True)
    now = time.time()
    for i in range(20):  # 20 other versions, the i-th last used i hours ago (plus a bit)
        p = parent / f"old{i:02d}"
        p.mkdir()
        (p / "kernel.nbi").write_text("x")
        age = i * 3600.0 + 60.0
        os.utime(p, (now - age, now - age))
    week = parent / "week-old"
    week.mkdir()
    os.utime(week, (now - 8 * 86400.0, now - 8 * 86400.0))
    recent = parent / "in-use-elsewhere"  # the 21st other folder, but used a minute ago
    recent.mkdir()
    _numba_cache._prune(parent, keep)
    left = {p.name for p in parent.iterdir()}
    assert "current" in left and "in-use-elsewhere" in left
    assert "week-old" not in left
    # 16 folders are kept (the current one and the 15 most recently used others); older
    # ones go once they have been idle for an hour.
    assert {f"old{i:02d}" for i in range(14)} <= left
    assert not left & {f"old{i:02d}" for i in range(14, 20)}
    assert len(left) == 16
