"""The quality table's bookkeeping in ``benchmarks/bench_continuous.py``.

Its permutation test, its refusal of a seed listed twice, and ``--fill``, which runs
the (env, algorithm, library, seed) runs a results file still lacks.
"""

from __future__ import annotations

import fcntl
import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_continuous.py"


@pytest.fixture(scope="module")
def bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_continuous", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    path = list(sys.path)  # the script puts benchmarks/ first on sys.path: not for the tests
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path[:] = path
    return module


def _line(env: str, algo: str, lib: str, seed: int, ret: float, steps: int = 200_000) -> str:
    run = dict(env=env, algo=algo, lib=lib, seed=seed, steps=steps, mean_return=ret)
    return json.dumps(run) + "\n"


def test_exact_p_counts_every_split_of_the_pooled_returns(bench: ModuleType) -> None:
    # [3, 4] against [1, 2]: of the C(4, 2) = 6 splits only the observed one has a
    # difference of means of 2 or more
    assert bench.exact_p([3.0, 4.0], [1.0, 2.0]) == pytest.approx(1 / 6)
    assert bench.exact_p([1.0, 2.0], [3.0, 4.0]) == pytest.approx(1.0)
    # [5, 1] against [2, 3, 4] (mean difference 0): splits with a difference >= 0
    # are those whose pair sums to 6 or more: {5,1} {5,2} {5,3} {5,4} {2,4} {3,4} of 10
    assert bench.exact_p([5.0, 1.0], [2.0, 3.0, 4.0]) == pytest.approx(6 / 10)
    assert bench.exact_p([1.0], [2.0, 3.0]) is None


def test_exact_p_equals_scipys_enumeration_of_every_split(bench: ModuleType) -> None:
    # the meet-in-the-middle count against scipy listing all C(n, k) splits, on groups
    # of 2 to 7 values, with many ties (small integers) and without (wide normals)
    from scipy.stats import permutation_test

    def diff(x: np.ndarray, y: np.ndarray, axis: int) -> np.ndarray:
        return np.mean(x, axis=axis) - np.mean(y, axis=axis)  # type: ignore[no-any-return]

    rng = np.random.default_rng(3)
    for case in range(60):
        k, m = (int(v) for v in rng.integers(2, 8, size=2))
        values = rng.integers(0, 5, size=k + m) if case % 2 else rng.normal(0, 1e3, k + m)
        higher, lower = [float(v) for v in values[:k]], [float(v) for v in values[k:]]
        expected = permutation_test(
            (higher, lower), diff, permutation_type="independent", alternative="greater",
            n_resamples=np.inf, vectorized=True,
        ).pvalue  # fmt: skip
        assert bench.exact_p(higher, lower) == pytest.approx(expected, abs=1e-12), case


def test_exact_p_counts_forty_million_splits_and_refuses_more_than_40(bench: ModuleType) -> None:
    # 14 against 14 with the groups 0..13 and 14..27: the first group's sum 91 is the
    # smallest of any 14-subset, so every split is at least as high in the other order
    # and exactly one (the observed) as low
    low, high = [float(v) for v in range(14)], [float(v) for v in range(14, 28)]
    assert bench.exact_p(high, low) == pytest.approx(1 / 40_116_600)
    assert bench.exact_p(low, high) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="at most 40 values, got 41"):
        bench.exact_p([0.0] * 20, [1.0] * 21)


def test_permutation_p_is_exact_p_up_to_40_pooled_values(bench: ModuleType) -> None:
    rng = np.random.default_rng(5)
    values = [float(v) for v in rng.normal(7000, 800, 40)]
    assert bench.permutation_p(values[:20], values[20:]) == (
        bench.exact_p(values[:20], values[20:]),
        True,
    )
    assert bench.permutation_p([1.0], [2.0, 3.0]) == (None, True)


def test_permutation_p_estimates_beyond_40_within_its_standard_error(bench: ModuleType) -> None:
    # 0/1 returns, 21 against 21: a split's difference of means is at least the observed
    # one exactly when its first group holds at least as many ones, so the exact p-value
    # is a hypergeometric tail (21 ones among 42, 14 or more of them in a group of 21)
    from scipy.stats import hypergeom

    higher, lower = [1.0] * 14 + [0.0] * 7, [1.0] * 7 + [0.0] * 14
    exact = float(hypergeom.sf(13, 42, 21, 21))
    p, is_exact = bench.permutation_p(higher, lower, resamples=200_000, seed=1)
    assert not is_exact and p is not None
    assert abs(p - exact) < 4 * np.sqrt(exact * (1 - exact) / 200_000), (p, exact)
    # same seed, same estimate; another seed draws other splits
    assert bench.permutation_p(higher, lower, resamples=200_000, seed=1) == (p, False)
    assert bench.permutation_p(higher, lower, resamples=200_000, seed=2)[0] != p
    # (1 + b) / (1 + B): the one most extreme split among C(42, 21) is almost never drawn,
    # and the estimate is then 1 / (1 + B), never 0; the least extreme is always matched
    assert bench.permutation_p([1.0] * 21, [0.0] * 21, resamples=999) == (1 / 1000, False)
    assert bench.permutation_p([0.0] * 21, [1.0] * 21, resamples=999) == (1.0, False)


def test_p_cells_mark_an_estimate(bench: ModuleType) -> None:
    assert bench._p_cell((None, True)) == "-"
    assert bench._p_cell((0.0684, True)) == "0.068"
    assert bench._p_cell((0.0684, False)) == "≈0.068"


def test_difference_ci_resamples_each_library_on_its_own(bench: ModuleType) -> None:
    # SB3 constant at 5: the difference is policylab's resampled mean minus 5, whose
    # lowest and highest values (1 and 3, each with probability 1/4 for two runs) are
    # the 2.5% and 97.5% quantiles
    assert bench.difference_ci([6.0, 8.0], [5.0, 5.0, 5.0]) == pytest.approx((1.0, 3.0))
    # both constant: the interval is the one difference
    assert bench.difference_ci([2.0, 2.0], [7.0, 7.0]) == pytest.approx((-5.0, -5.0))
    # the other way round, the same interval negated, up to resampling noise; same seed,
    # same interval
    ours, theirs = [1.0, 4.0, 2.0, 8.0], [3.0, 5.0, 9.0]
    lo, hi = bench.difference_ci(ours, theirs, reps=4000)
    assert lo < np.mean(ours) - np.mean(theirs) < hi
    assert bench.difference_ci(ours, theirs, reps=4000) == (lo, hi)
    back = bench.difference_ci(theirs, ours, reps=4000)
    assert back == pytest.approx((-hi, -lo), abs=0.35)


def test_a_seed_listed_twice_is_refused_naming_both_lines(
    bench: ModuleType, tmp_path: Path
) -> None:
    path = tmp_path / "quality.jsonl"
    path.write_text(
        _line("Hopper-v5", "td3", "SB3", 0, 749.1)
        + _line("Hopper-v5", "td3", "SB3", 1, 900.0)
        + _line("Hopper-v5", "td3", "SB3", 0, 749.1)
    )
    with pytest.raises(SystemExit, match=r"line 3: seed 0 of .*Hopper-v5.* \(first: .*line 1\)"):
        bench.read_runs([path])


def test_missing_runs_skip_those_done_and_pair_the_libraries(
    bench: ModuleType, tmp_path: Path
) -> None:
    path = tmp_path / "quality.jsonl"
    assert len(bench.missing_runs(path, ["Hopper-v5"], ["sac", "td3"], ["policylab", "SB3"],
                                  [0, 1], 200_000)) == 8  # fmt: skip
    path.write_text(
        _line("Hopper-v5", "td3", "SB3", 0, 749.1)
        + _line("Hopper-v5", "TD3", "policylab", 0, 3065.2)  # the algorithm in any case
        + _line("Hopper-v5", "sac", "SB3", 1, 3358.6, steps=100_000)  # another budget
    )
    missing = bench.missing_runs(
        path, ["Hopper-v5", "Walker2d-v5"], ["sac", "td3"], ["policylab", "SB3"], [0, 1], 200_000
    )
    assert missing[:6] == [
        ("Hopper-v5", "sac", "SB3", 0),
        ("Hopper-v5", "sac", "policylab", 0),
        ("Hopper-v5", "sac", "SB3", 1),
        ("Hopper-v5", "sac", "policylab", 1),
        ("Hopper-v5", "td3", "SB3", 1),
        ("Hopper-v5", "td3", "policylab", 1),
    ]
    assert len(missing) == 6 + 8 and missing[6] == ("Walker2d-v5", "sac", "SB3", 0)


def test_fill_runs_what_is_missing_once_and_a_second_fill_runs_nothing(tmp_path: Path) -> None:
    results, logs = tmp_path / "quality.jsonl", tmp_path / "logs"
    results.write_text(_line("Pendulum-v1", "td3", "policylab", 0, -150.0, steps=200))
    command = [
        sys.executable, str(SCRIPT), "--fill", str(results), "--envs", "Pendulum-v1",
        "--algos", "td3", "--libs", "policylab", "--seed-list", "0", "1", "--budget", "200",
        "--episodes", "1", "--cores", "0", "--log-dir", str(logs), "--poll", "0.2",
    ]  # fmt: skip
    out = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "1 runs of 200 env steps missing" in out.stdout
    assert "core 0: done Pendulum-v1 td3 policylab 1" in out.stdout
    runs = [json.loads(line) for line in results.read_text().splitlines()]
    assert [(r["seed"], r["steps"], r.get("episodes")) for r in runs] == [
        (0, 200, None),
        (1, 200, 1),
    ]
    assert "1 of" in runs[1]["machine"]  # pinned to the one core it was given
    assert (logs / "Pendulum-v1-td3-policylab-1.log").exists()
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "0 runs of 200 env steps missing" in again.stdout
    assert len(results.read_text().splitlines()) == 2


def test_a_second_fill_on_the_same_file_is_refused(tmp_path: Path) -> None:
    results = tmp_path / "quality.jsonl"
    with results.open("a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # as a running --fill holds it
        out = subprocess.run(
            [sys.executable, str(SCRIPT), "--fill", str(results), "--dry-run"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    assert out.returncode == 1
    assert f"another --fill is running on {results}" in out.stderr


def _plan(bench: ModuleType) -> Any:
    return bench.PlannedComparison(
        env="HalfCheetah-v5", algo="td3", steps=200_000, seeds=(3, 4, 5, 6), margin=0.10,
        fixed="today",
    )  # fmt: skip


def _records(lib: str, returns: dict[int, float], **run: Any) -> list[dict[str, Any]]:
    base = dict(env="HalfCheetah-v5", algo="td3", lib=lib, steps=200_000) | run
    return [base | dict(seed=s, mean_return=r) for s, r in returns.items()]


def test_a_planned_comparison_gives_no_result_until_every_planned_run_is_in(
    bench: ModuleType,
) -> None:
    records = (
        _records("SB3", {3: 10.0, 4: 11.0, 5: 12.0, 6: 13.0})
        + _records("policylab", {3: 1.0, 4: 2.0, 5: 3.0})
        # not the plan's: another seed, budget, env and algorithm
        + _records("policylab", {7: 1.0})
        + _records("policylab", {6: 1.0}, steps=100_000)
        + _records("policylab", {6: 1.0}, env="Hopper-v5")
        + _records("policylab", {6: 1.0}, algo="sac")
    )
    out = _plan(bench).read(records)
    assert "3 of 4 policylab runs and 4 of 4 SB3 runs are in" in out
    assert "p =" not in out and "interval" not in out


def test_a_planned_comparison_reports_both_rules_once_complete(bench: ModuleType) -> None:
    plan, seeds = _plan(bench), (3, 4, 5, 6)
    sb3 = _records("SB3", dict(zip(seeds, (1000.0, 1001.0, 1002.0, 1003.0), strict=True)))

    def read(ours: tuple[float, ...]) -> str:
        return str(plan.read(sb3 + _records("policylab", dict(zip(seeds, ours, strict=True)))))

    # far behind: every split's test is at its smallest p = 1 / C(8, 4), and the interval
    # is far below -10% of SB3's mean (-100.15)
    far = read((500.0, 501.0, 502.0, 503.0))
    assert "not shown not worse" in far and "SB3 ahead at the 5% level (p = 0.014)" in far
    assert "-100.2, -10% of SB3's mean" in far
    # behind on every seed, but by 20 of 1,001.5: SB3 is ahead, and policylab not worse
    near = read((980.0, 981.0, 982.0, 983.0))
    assert near.count("not worse") == 1 and "above -100.2" in near
    assert "SB3 ahead at the 5% level (p = 0.014)" in near
    assert "policylab - SB3 -20.0" in near
    # level: not worse, and SB3 not shown ahead
    level = read((1003.0, 1002.0, 1000.0, 1001.0))
    assert "not worse (interval's lower end" in level and "not shown not worse" not in level
    assert "SB3 not shown ahead" in level
