"""Exact planning against mdptoolbox-hiive and quantecon on sparse random MDPs.

    python benchmarks/bench_planning.py            # 10^4 and 10^6 states (about 20 min)
    python benchmarks/bench_planning.py --quick    # 10^4 only

Each (library, method) runs in its own subprocess with a time limit and a 16 GB address
space cap; the subprocess builds ``random_mdp(S, 4, 10, seed=0, gamma=0.95)``, converts
it to the library's input format (not timed), warms up, then times the solve alone and
records the peak resident memory added during the solve (sampled) and the
process's peak resident set. The parent then evaluates each returned policy exactly
and reports max_s v_*(s) - v_pi(s) against the reference v_* (our policy iteration,
cross-checked by value iteration at 1e-9).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

GAMMA = 0.95
TARGET = 1e-6
METHODS = {
    "policylab": ["vi", "vi-gs", "pi", "mpi", "lp"],
    "quantecon": ["vi", "pi", "mpi"],
    "mdptoolbox-hiive": ["vi", "vi-gs", "pi", "mpi"],
}
NAMES = {
    "vi": "value iteration",
    "vi-gs": "value iteration (Gauss-Seidel)",
    "pi": "policy iteration",
    "mpi": "modified policy iteration",
    "lp": "linear programming",
    "floor": "one bare CSR sweep (scipy, P @ v)",
}


def build(S: int) -> Any:
    from policylab.problems import random_mdp

    return random_mdp(S, 4, 10, seed=0, gamma=GAMMA)


class RssPeak:
    """Peak resident memory above the level at entry, sampled every 2 ms by a thread."""

    def __init__(self) -> None:
        self.page = os.sysconf("SC_PAGE_SIZE")
        self.base = self.peak = self.rss()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def rss(self) -> int:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * self.page

    def _run(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, self.rss())

    def __enter__(self) -> RssPeak:
        self._thread.start()
        return self

    def __exit__(self, *args: object) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self.rss())

    @property
    def extra_mb(self) -> float:
        return (self.peak - self.base) / 2**20


def worker(lib: str, method: str, S: int, out: str) -> None:
    """Run one solve and write {seconds, iterations, policy, memory} to ``out``."""
    resource.setrlimit(resource.RLIMIT_AS, (16 * 2**30, 16 * 2**30))
    import policylab as pl

    mdp = build(S)
    A = mdp.n_actions
    iters: int = 0
    floor = floor_seconds(mdp)  # in this process, just before the solve
    mdp.expected_reward  # noqa: B018  (derived once per model; every library is given r(s, a))
    if lib == "policylab":
        mdp.__dict__.pop("transition_matrix", None)  # our solvers read the outcome table
    if lib == "policylab":
        from policylab.planning import linear_programming, modified_policy_iteration

        small = build(50)  # compile / load the kernels outside the timing
        pl.value_iteration(small, gauss_seidel=True)
        pl.policy_iteration(small, solver="krylov")
        modified_policy_iteration(small)
        run = {
            "vi": lambda: pl.value_iteration(mdp, tol=TARGET),
            "vi-gs": lambda: pl.value_iteration(mdp, tol=TARGET, gauss_seidel=True),
            "pi": lambda: pl.policy_iteration(mdp),
            "mpi": lambda: modified_policy_iteration(mdp, tol=TARGET),
            "lp": lambda: linear_programming(mdp),
        }[method]
        with RssPeak() as mem:
            t0 = time.perf_counter()
            res = run()
            seconds = time.perf_counter() - t0
        policy = res.policy.action_indices()
        iters = res.iterations
        extra = {"error_bound": res.error_bound}
        if method in ("vi", "vi-gs"):
            from policylab.planning._kernels import (
                gauss_seidel_optimality_sweep,
                optimality_sweep,
            )

            w = res.v.copy()
            if method == "vi":
                extra["sweep"] = best_of(lambda: optimality_sweep(mdp, GAMMA, w))
            else:
                extra["sweep"] = best_of(lambda: gauss_seidel_optimality_sweep(mdp, GAMMA, w))
    elif lib == "quantecon":
        import quantecon as qe

        ddp = qe.markov.DiscreteDP(
            np.asarray(mdp.expected_reward).ravel(),
            mdp.transition_matrix,
            GAMMA,
            np.repeat(np.arange(S), A),
            np.tile(np.arange(A), S),
        )
        qe_method = {
            "vi": "value_iteration",
            "pi": "policy_iteration",
            "mpi": "modified_policy_iteration",
        }[method]
        with RssPeak() as mem:
            t0 = time.perf_counter()
            res = ddp.solve(method=qe_method, epsilon=TARGET, max_iter=100_000)
            seconds = time.perf_counter() - t0
        policy = np.asarray(res.sigma)
        iters = int(res.num_iter)
        extra = {}
        if method == "vi":
            w = np.asarray(res.v).copy()
            extra["sweep"] = best_of(lambda: ddp.bellman_operator(w))
    else:
        import scipy.sparse as sp
        from hiive.mdptoolbox import mdp as hm

        P = [sp.csr_matrix(mdp.transitions(a)) for a in range(A)]
        R = np.asarray(mdp.expected_reward)
        cls = {
            "vi": lambda: hm.ValueIteration(
                P, R, GAMMA, epsilon=TARGET, max_iter=100_000, skip_check=True
            ),
            "vi-gs": lambda: hm.ValueIterationGS(
                P, R, GAMMA, epsilon=TARGET, max_iter=100_000, skip_check=True
            ),
            "pi": lambda: hm.PolicyIteration(P, R, GAMMA, max_iter=100_000, skip_check=True),
            "mpi": lambda: hm.PolicyIterationModified(
                P, R, GAMMA, epsilon=TARGET, max_iter=100_000, skip_check=True
            ),
        }[method]
        with RssPeak() as mem:
            t0 = time.perf_counter()
            solver = cls()
            solver.run()
            seconds = time.perf_counter() - t0
        policy = np.asarray(solver.policy)
        iters = int(solver.iter)
        extra = {}
    np.save(out + ".npy", policy.astype(np.int64))
    Path(out + ".json").write_text(
        json.dumps(
            {
                "seconds": seconds,
                "iterations": iters,
                "peak_solve_mb": mem.extra_mb,
                "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                "model_mb": mdp.nbytes / 2**20,
                "floor": floor,
                **extra,
            }
        )
    )


def best_of(fn: Any, repeats: int = 7) -> float:
    """The fastest of a few calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def floor_seconds(mdp: Any, repeats: int = 7) -> float:
    """The fastest of a few bare ``P @ v`` products with the (S * A, S) CSR matrix."""
    tm = mdp.transition_matrix
    v = np.random.default_rng(0).random(mdp.n_states)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        tm @ v
        times.append(time.perf_counter() - t0)
    return min(times)


def run_case(lib: str, method: str, S: int, limit: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "res")
        cmd = [sys.executable, __file__, "--worker", lib, method, str(S), out]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=limit)
        except subprocess.TimeoutExpired:
            return {"status": f"> {limit:.0f} s (stopped)"}
        if proc.returncode != 0 or not os.path.exists(out + ".json"):
            last = (proc.stderr.strip().splitlines() or ["?"])[-1][:90]
            return {"status": f"failed: {last}", "wall": time.perf_counter() - t0}
        data = json.loads(Path(out + ".json").read_text())
        data["policy"] = np.load(out + ".npy")
        data["status"] = "ok"
        return data


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5])
        return 0
    import policylab as pl
    from _report import write_section

    quick = "--quick" in sys.argv
    sizes = [10**4] if quick else [10**4, 10**6]
    limits = {10**4: 60.0, 10**6: 90.0}
    sections = []
    for S in sizes:
        print(f"== S = {S}", flush=True)
        mdp = build(S)
        ref = pl.policy_iteration(mdp)
        check = pl.value_iteration(mdp, tol=1e-9)
        assert np.max(np.abs(check.v - ref.v)) <= 1e-8
        v_star = ref.v
        floor = floor_seconds(mdp)
        rows = []
        for lib, methods in METHODS.items():
            for method in methods:
                if method == "lp" and S > 10**4:
                    continue
                print(f"   {lib} {method} ...", flush=True)
                r = run_case(lib, method, S, limits[S])
                if r["status"] == "ok":
                    v_pi = pl.evaluate_policy(mdp, pl.Policy.from_actions(mdp, r["policy"]))
                    r["error"] = float(np.max(v_star - v_pi))
                print(f"      {r.get('seconds', r['status'])}", flush=True)
                rows.append((lib, method, r))
        sections.append(table(S, mdp, floor, rows))
        del mdp
    body = "\n\n".join(sections) + "\n\n" + NOTES
    write_section(
        "Exact planning",
        "python benchmarks/bench_planning.py" + (" --quick" if quick else ""),
        body,
    )
    print(body)
    return 0


def table(S: int, mdp: Any, floor: float, rows: list[tuple[str, str, dict[str, Any]]]) -> str:
    model_mb = mdp.nbytes / 2**20
    lines = [
        f"### random_mdp({S:,}, 4 actions, 10 successors), gamma {GAMMA}: "
        f"model {model_mb:,.0f} MiB, {mdp.n_outcomes:,} outcomes",
        "",
        f"Floor: {NAMES['floor']} = {floor * 1e3:.2f} ms in the parent process; each "
        "worker measures it again just before its solve, and the per-sweep ratio uses "
        "that worker's own floor.",
        "",
        "| library | method | time (s) | iterations | one sweep / floor | "
        "max v* - v_pi | within 1e-6 | solve extra RSS (MiB) | process peak RSS (MiB) |",
        "|---|---|---:|---:|---:|---:|:---:|---:|---:|",
    ]
    best: dict[str, tuple[float, str]] = {}
    for lib, method, r in rows:
        if r["status"] != "ok":
            lines.append(f"| {lib} | {NAMES[method]} | {r['status']} | | | | | | |")
            continue
        sweep = ""
        if r.get("sweep"):
            sweep = f"{r['sweep'] / r['floor']:.2f}x"
        ok = r["error"] <= TARGET
        if ok and (lib not in best or r["seconds"] < best[lib][0]):
            best[lib] = (r["seconds"], NAMES[method])
        lines.append(
            f"| {lib} | {NAMES[method]} | {r['seconds']:.3g} | {r['iterations']} | {sweep} | "
            f"{r['error']:.2e} | {'yes' if ok else '**no**'} | {r['peak_solve_mb']:,.0f} | "
            f"{r['maxrss_mb']:,.0f} |"
        )
    lines += ["", "Best method of each library (among those within 1e-6 of optimal):", ""]
    lines += [
        f"- {lib}: {name}, {sec:.3g} s"
        for lib, (sec, name) in sorted(best.items(), key=lambda x: x[1][0])
    ]
    return "\n".join(lines)


NOTES = """Notes.
- Time is the solve alone (input conversion excluded), single-threaded, on a 2-core
  machine shared with four other developers working at the same time: timings carry
  noise of tens of percent. "> N s (stopped)" means the subprocess was killed at its
  time limit.
- "max v* - v_pi" is the error of the returned policy (its value by an exact
  evaluation against the reference v_*); "within 1e-6" is the issue's success
  criterion. Where every library returns the same optimal policy the column shows the
  same ~1e-10: the accuracy of the evaluation itself, not a difference of policies.
  Each library was asked for 1e-6 (policylab: tol on v, with the proven bound;
  quantecon and hiive: epsilon).
- "one sweep / floor": the fastest of 7 Bellman optimality sweeps (policylab's
  compiled sweep, which reads the outcome table in one pass and takes the max over
  actions; quantecon's ``bellman_operator``) over the fastest of 7 bare scipy CSR
  products P @ v with the (S * A, S) matrix, both timed in the same worker. Total
  time / iterations is higher at 10^4 states, where the fixed costs of a solve (the
  final q and greedy policy) weigh as much as a few sweeps.
- Memory: "solve extra RSS" is the peak resident memory during the solve above the
  level just before it (sampled every 2 ms by a thread, so it includes C allocations
  such as SuperLU's factors); "process peak RSS" includes the interpreter, the
  libraries, building the model and converting it to the library's format.
- policylab's value iteration stops by MacQueen's bounds (proven |v - v*| <= tol);
  policy iteration evaluates each policy to a proven 1e-10 relative accuracy (sparse
  LU up to 5,000 states; above, warm-started sweeps stopped by MacQueen's bounds,
  with GMRES on a matrix-free operator if they mix slowly). Linear programming is
  there as an independent check, not for speed (HiGHS).
- mdptoolbox-hiive's ValueIterationGS fails on sparse transition matrices (a
  TypeError inside the library), so it has no time."""


if __name__ == "__main__":
    sys.exit(main())
