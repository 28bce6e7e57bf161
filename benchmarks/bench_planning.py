"""Exact planning on families of MDPs, against quantecon and mdptoolbox-hiive, in one run.

    python benchmarks/bench_planning.py --help
    python benchmarks/bench_planning.py                       # the suite; writes BENCHMARKS.md
    python benchmarks/bench_planning.py --large               # adds the 10^5-10^6-state cases
    python benchmarks/bench_planning.py --families jacks-car-rental,inventory --no-write

Families: random sparse (fast mixing); slippery gridworlds at gamma 0.99 and 0.999
(slow mixing); a long chain (the worst case of synchronous value iteration);
inventory management and Jack's car rental (dense rows, action sets that depend on
the state), at their textbook sizes, at larger sizes whose outcome table still fits
(``inventory-1000``, ``jacks-30``) and at 10^5-10^6 states where only the
post-decision model fits; an episodic gamma = 1 shortest path on the gridworld.

Each (library, family) runs in its own subprocess (16 GB address-space cap): it builds
the model, converts it to the library's input (not timed), warms the library up on a
small model, then runs each method in turn with a time limit, timing the solve alone
and sampling the resident memory it adds. The bare sparse matrix-vector product P @ v
over the (S * A, S) matrix (scipy CSR) is timed in the same process: the floor of any
sweep (on the post-decision rows, the bare kernel product K v instead). The parent
evaluates every returned policy exactly and reports its error against v_* (policy
iteration with exact evaluation, cross-checked by ordered Gauss-Seidel sweeps at
1e-9; on families without an outcome table, the post-decision model solved by
policylab's auto to 1e-10 (policy iteration, exact, where policies split into small
strongly connected components; modified policy iteration to a proven 1e-10 otherwise),
cross-checked by value iteration at 1e-9).
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

TARGET = 1e-6
#: Solves up to this long are run once more under tracemalloc for their peak memory.
MEMORY_RUN_MAX_S = 5.0
LIMIT = float(os.environ.get("BENCH_PLANNING_LIMIT", "30"))  # seconds per method (--limit)

FAMILIES: dict[str, tuple[str, Callable[[], Any]]] = {}
#: The same MDP as a PostDecisionMDP, for the families that have one.
POST_DECISION: dict[str, Callable[[], Any]] = {}
#: Families whose outcome table does not fit (post-decision model only).
NO_TABLE: dict[str, str] = {}


def family(
    name: str, title: str, large: bool = False, post_decision: Callable[[], Any] | None = None
) -> Callable[[Any], Any]:
    def deco(fn: Callable[[], Any]) -> Callable[[], Any]:
        FAMILIES[name] = (title, fn)
        if large:
            LARGE.add(name)
        if post_decision is not None:
            POST_DECISION[name] = post_decision
        return fn

    return deco


LARGE: set[str] = set()


def _pd_inventory(capacity: int, max_order: int | None) -> Callable[[], Any]:
    def build() -> Any:
        from policylab.problems import inventory_management

        return inventory_management(capacity=capacity, max_order=max_order, post_decision=True)

    return build


def _pd_jacks(max_cars: int) -> Callable[[], Any]:
    def build() -> Any:
        from policylab.problems import jacks_car_rental

        return jacks_car_rental(max_cars=max_cars, post_decision=True)

    return build


@family("random", "random_mdp(100,000 states, 4 actions, 10 successors), gamma 0.95")
def _random() -> Any:
    from policylab.problems import random_mdp

    return random_mdp(100_000, 4, 10, seed=0, gamma=0.95)


@family("grid-0.99", "slip_gridworld(200 x 200 = 40,000 states, slip 0.1), gamma 0.99")
def _grid99() -> Any:
    from policylab.problems.generators import slip_gridworld

    return slip_gridworld(200, 0.1, gamma=0.99)


@family("grid-0.999", "slip_gridworld(200 x 200, slip 0.1), gamma 0.999")
def _grid999() -> Any:
    from policylab.problems.generators import slip_gridworld

    return slip_gridworld(200, 0.1, gamma=0.999)


@family("chain-0.999", "long_chain(10,000 states, right succeeds 0.9), gamma 0.999")
def _chain() -> Any:
    from policylab.problems.generators import long_chain

    return long_chain(10_000, 0.9, gamma=0.999)


@family(
    "inventory",
    "inventory_management(capacity 150: 151 states, up to 151 actions), gamma 0.95",
    post_decision=_pd_inventory(150, None),
)
def _inventory() -> Any:
    from policylab.problems import inventory_management

    return inventory_management(capacity=150)


@family(
    "inventory-1000",
    "inventory_management(capacity 1000, max_order 50: 1,001 states, 51 actions), gamma 0.95",
    post_decision=_pd_inventory(1000, 50),
)
def _inventory1000() -> Any:
    # the outcome table of the same MDP (from_dynamics would take minutes at this size)
    return _pd_inventory(1000, 50)().to_finite_mdp()


@family(
    "jacks-car-rental",
    "jacks_car_rental() (441 states, 11 actions, dense rows), gamma 0.9",
    post_decision=_pd_jacks(20),
)
def _jack() -> Any:
    from policylab.problems import jacks_car_rental

    return jacks_car_rental()


@family(
    "jacks-30",
    "jacks_car_rental(max_cars=30) (961 states, 11 actions, dense rows), gamma 0.9",
    post_decision=_pd_jacks(30),
)
def _jack30() -> Any:
    from policylab.problems import jacks_car_rental

    return jacks_car_rental(max_cars=30)


@family(
    "jacks-1e5",
    "jacks_car_rental(max_cars=316) (100,489 states, 11 actions), gamma 0.9",
    post_decision=_pd_jacks(316),
)
def _jack1e5() -> Any:
    return None


NO_TABLE["jacks-1e5"] = "its outcome table would hold 1.1 * 10^11 outcomes (1.7 TB)"


@family(
    "inventory-1e5",
    "inventory_management(capacity 99,999, max_order 20: 10^5 states, 21 actions), gamma 0.95",
    large=True,
    post_decision=_pd_inventory(99_999, 20),
)
def _inventory1e5() -> Any:
    return None


NO_TABLE["inventory-1e5"] = "its outcome table would hold about 4 * 10^8 outcomes (8 GB)"


@family(
    "jacks-1e6",
    "jacks_car_rental(max_cars=999) (10^6 states, 11 actions), gamma 0.9",
    large=True,
    post_decision=_pd_jacks(999),
)
def _jack1e6() -> Any:
    return None


NO_TABLE["jacks-1e6"] = "its outcome table would hold 1.1 * 10^13 outcomes"


@family("shortest-path", "slip_gridworld(200 x 200, slip 0.1), gamma 1 (stochastic shortest path)")
def _ssp() -> Any:
    from policylab.problems.generators import slip_gridworld

    return slip_gridworld(200, 0.1, gamma=1.0)


@family("random-1e6", "random_mdp(10^6 states, 4 actions, 10 successors), gamma 0.95", large=True)
def _random6() -> Any:
    from policylab.problems import random_mdp

    return random_mdp(1_000_000, 4, 10, seed=0, gamma=0.95)


@family("grid-1e6", "slip_gridworld(1000 x 1000 = 10^6 states, slip 0.1), gamma 0.99", large=True)
def _grid6() -> Any:
    from policylab.problems.generators import slip_gridworld

    return slip_gridworld(1000, 0.1, gamma=0.99)


# Run in this order; an anchor's policy iteration goes last, since its sparse LU can
# hang in C code (past the per-method alarm) on large random graphs.
METHODS = {
    "policylab": ["auto", "vi", "vi-gs", "pi", "mpi"],
    "policylab, 2 threads": ["auto", "vi", "mpi"],
    "policylab post-decision": ["auto", "vi", "pi", "mpi"],
    "policylab post-decision, 2 threads": ["auto", "vi", "mpi"],
    "quantecon": ["vi", "mpi", "pi"],
    "mdptoolbox-hiive": ["vi", "vi-gs", "mpi", "pi"],
}
#: numba threads of each library's worker (every other library is single-threaded:
#: BLAS and OpenMP pools are held to one thread in all workers, except the 2-thread
#: post-decision rows, whose kernel products K v are BLAS matrix products on 2 threads).
THREADS = {"policylab, 2 threads": 2, "policylab post-decision, 2 threads": 2}
NAMES = {
    "auto": "auto",
    "vi": "value iteration",
    "vi-gs": "value iteration (Gauss-Seidel)",
    "pi": "policy iteration",
    "mpi": "modified policy iteration",
}


def method_name(lib: str, method: str) -> str:
    """The method's name in the tables (policylab's MPI adapts m; quantecon's uses k = 20)."""
    if lib.startswith("policylab") and method == "mpi":
        return "modified policy iteration (adaptive m)"
    return NAMES[method]


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


def best_of(fn: Callable[[], Any], repeats: int = 7) -> float:
    """The fastest of a few calls of ``fn``."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def forget(mdp: Any) -> None:
    """Drop what policylab keeps with a model between solves (its shared rows, the
    distances to its terminal states), so that each timed solve finds them itself."""
    from policylab.planning import _kernels

    _kernels._SHARED.pop(mdp, None)
    _kernels._DISTANCES.pop(mdp, None)


def floor_seconds(mdp: Any) -> float:
    """The fastest of a few bare ``P @ v`` products with the (S * A, S) CSR matrix."""
    tm = mdp.transition_matrix
    v = np.random.default_rng(0).random(mdp.n_states)
    return best_of(lambda: tm @ v)


class TimeLimitError(Exception):
    pass


def _alarm(*_: object) -> None:
    raise TimeLimitError


def sa_pairs(mdp: Any) -> tuple[np.ndarray, Any, np.ndarray, np.ndarray]:
    """The model as state-action pairs (quantecon's sparse input): terminal states get
    one zero-reward self-loop, unavailable actions no row."""
    import scipy.sparse as sp

    S, A = mdp.n_states, mdp.n_actions
    rows = np.flatnonzero(mdp.action_mask.ravel())
    term = np.flatnonzero(mdp.terminal)
    Q = sp.vstack(
        [
            mdp.transition_matrix[rows],
            sp.csr_array((np.ones(len(term)), (np.arange(len(term)), term)), shape=(len(term), S)),
        ],
        format="csr",
    )
    R = np.concatenate([mdp.expected_reward.ravel()[rows], np.zeros(len(term))])
    s_idx = np.concatenate([rows // A, term])
    a_idx = np.concatenate([rows % A, np.zeros(len(term), dtype=np.int64)])
    order = np.lexsort((a_idx, s_idx))
    return R[order], Q[order], s_idx[order], a_idx[order]


def worker(lib: str, fam: str, out: str) -> None:
    """Run every method of ``lib`` on ``fam``; write {method: result} to ``out``."""
    resource.setrlimit(resource.RLIMIT_AS, (16 * 2**30, 16 * 2**30))
    signal.signal(signal.SIGALRM, _alarm)
    import policylab as pl

    t0 = time.perf_counter()
    first = None
    ours_lib = lib.startswith("policylab")
    pd_lib = "post-decision" in lib
    skip = (
        "no post-decision model for this family"
        if pd_lib and fam not in POST_DECISION
        else f"no outcome table: {NO_TABLE[fam]}"
        if not pd_lib and fam in NO_TABLE
        else ""
    )
    if skip:
        Path(out + ".json").write_text(json.dumps({"_skip": skip}))
        return
    if ours_lib:
        small = pl.problems.random_mdp(50, 2, 3)
        pl.value_iteration(small)  # the first compiled call of a fresh process
        first = time.perf_counter() - t0
    mdp = POST_DECISION[fam]() if pd_lib else FAMILIES[fam][1]()
    g = mdp.gamma
    S, A = mdp.n_states, mdp.n_actions
    if pd_lib:  # the floor of a post-decision backup: the bare kernel product K v
        v_floor = np.random.default_rng(0).random(S)
        floor = best_of(lambda: mdp.kernel.expect(v_floor))
    else:
        floor = floor_seconds(mdp)
    mdp.expected_reward  # noqa: B018  (derived once per model; every library is given r(s, a))
    results: dict[str, Any] = {"_floor": floor, "_model_mb": mdp.nbytes / 2**20, "_first": first}
    runs: dict[str, Callable[[], tuple[np.ndarray, np.ndarray, int, str]]] = {}
    sweep: dict[str, Callable[[], Any]] = {}
    if pd_lib:
        from policylab.planning import postdecision, solve

        for warm in (
            pl.problems.inventory_management(capacity=15, post_decision=True),
            pl.problems.jacks_car_rental(max_cars=6, max_move=2, post_decision=True),
            pl.problems.jacks_car_rental(max_cars=70, post_decision=True),  # GMRES evaluation
        ):
            for method in METHODS[lib]:
                solve(warm, method)

        def ours_pd(method: str) -> Callable[[], tuple[np.ndarray, np.ndarray, int, str]]:
            def run() -> tuple[np.ndarray, np.ndarray, int, str]:
                res = solve(mdp, method, tol=TARGET)
                note = res.info.get("auto", {}).get("method", "")
                return res.v, res.policy.action_indices(), res.iterations, note

            return run

        runs = {m: ours_pd(m) for m in METHODS[lib]}
        w = np.zeros(S)
        sweep["vi"] = lambda: postdecision.optimality_backup(mdp, g, w)
    elif ours_lib:
        from policylab.planning import modified_policy_iteration, solve
        from policylab.planning._kernels import optimality_values

        for name in ("slip-gridworld", "long-chain"):
            warm = pl.problems.get_problem(name)
            solve(warm, "vi-gs")
            pl.policy_iteration(warm, solver="krylov")
            modified_policy_iteration(warm)
        # the shared-row and dense-LU paths, on small models of the same array types
        for warm in (
            pl.problems.inventory_management(capacity=15),
            pl.problems.jacks_car_rental(max_cars=6, max_move=2),
            pl.problems.random_mdp(300, 4, 10, seed=1),
        ):
            for method in METHODS[lib]:
                solve(warm, method)
            pl.policy_iteration(warm)
        mdp.__dict__.pop("transition_matrix", None)  # our solvers read the outcome table

        def ours(method: str) -> Callable[[], tuple[np.ndarray, np.ndarray, int, str]]:
            def run() -> tuple[np.ndarray, np.ndarray, int, str]:
                forget(mdp)
                res = solve(mdp, method, tol=TARGET)
                note = res.info.get("auto", {}).get("method", "")
                return res.v, res.policy.action_indices(), res.iterations, note

            return run

        runs = {m: ours(m) for m in METHODS[lib]}
        w = np.zeros(S)
        sweep["vi"] = lambda: optimality_values(mdp, g, w)
    elif lib == "quantecon":
        if g >= 1.0:
            results["_skip"] = "gamma = 1: quantecon disables its infinite-horizon methods"
        else:
            import quantecon as qe

            R, Q, s_idx, a_idx = sa_pairs(mdp)
            ddp = qe.markov.DiscreteDP(R, Q, g, s_idx, a_idx)
            warm_r, warm_q, ws, wa = sa_pairs(pl.problems.random_mdp(50, 2, 3))
            warm = qe.markov.DiscreteDP(warm_r, warm_q, 0.9, ws, wa)
            for m in ("value_iteration", "policy_iteration", "modified_policy_iteration"):
                warm.solve(method=m)

            def theirs(method: str) -> Callable[[], tuple[np.ndarray, np.ndarray, int, str]]:
                def run() -> tuple[np.ndarray, np.ndarray, int, str]:
                    res = ddp.solve(method=method, epsilon=TARGET, max_iter=1_000_000)
                    return np.asarray(res.v), np.asarray(res.sigma), int(res.num_iter), ""

                return run

            runs = {
                "vi": theirs("value_iteration"),
                "pi": theirs("policy_iteration"),
                "mpi": theirs("modified_policy_iteration"),
            }
            v0 = np.zeros(S)
            sweep["vi"] = lambda: ddp.bellman_operator(v0)
    else:
        if not mdp.action_mask[~mdp.terminal].all():
            results["_skip"] = "needs every action in every state (this family restricts A(s))"
        else:
            import scipy.sparse as sp
            from hiive.mdptoolbox import mdp as hm

            term = np.flatnonzero(mdp.terminal)
            P = []
            for a in range(A):
                m = sp.lil_matrix(mdp.transitions(mdp.actions[a]))
                for t in term:
                    m[t, t] = 1.0
                P.append(sp.csr_matrix(m))
            Rm = np.where(mdp.action_mask, mdp.expected_reward, 0.0)
            gh = min(g, 1.0)
            cls = {
                "vi": lambda: hm.ValueIteration(
                    P, Rm, gh, epsilon=TARGET, max_iter=1_000_000, skip_check=True
                ),
                "vi-gs": lambda: hm.ValueIterationGS(
                    P, Rm, gh, epsilon=TARGET, max_iter=1_000_000, skip_check=True
                ),
                "pi": lambda: hm.PolicyIteration(P, Rm, gh, max_iter=1_000_000, skip_check=True),
                "mpi": lambda: hm.PolicyIterationModified(
                    P, Rm, gh, epsilon=TARGET, max_iter=1_000_000, skip_check=True
                ),
            }

            def hiive(method: str) -> Callable[[], tuple[np.ndarray, np.ndarray, int, str]]:
                def run() -> tuple[np.ndarray, np.ndarray, int, str]:
                    solver = cls[method]()
                    solver.run()
                    return (
                        np.asarray(solver.V, dtype=float),
                        np.asarray(solver.policy),
                        int(solver.iter),
                        "",
                    )

                return run

            runs = {m: hiive(m) for m in METHODS[lib]}
    for method, run in runs.items():
        entry: dict[str, Any] = {}
        try:
            with RssPeak() as mem:
                signal.setitimer(signal.ITIMER_REAL, LIMIT)
                t1 = time.perf_counter()
                try:
                    v, policy, iters, note = run()
                finally:
                    signal.setitimer(signal.ITIMER_REAL, 0)
                seconds = time.perf_counter() - t1
                # short solves: the best of up to 5 runs (one time slice lost to another
                # job on a loaded machine is several times such a solve)
                for _ in range(4):
                    if seconds > 0.5:
                        break
                    t1 = time.perf_counter()
                    run()
                    seconds = min(seconds, time.perf_counter() - t1)
            peak_mb = mem.extra_mb
            if seconds <= MEMORY_RUN_MAX_S:
                # one more run, untimed, under tracemalloc: the peak of every array
                # allocated from Python (NumPy, SciPy), which the 2 ms RSS samples miss
                tracemalloc.start()
                run()
                peak_mb = max(peak_mb, tracemalloc.get_traced_memory()[1] / 2**20)
                tracemalloc.stop()
            np.save(f"{out}.{method}.v.npy", np.asarray(v, dtype=float))
            np.save(f"{out}.{method}.pi.npy", np.asarray(policy).astype(np.int64))
            entry = {
                "status": "ok",
                "seconds": seconds,
                "iterations": iters,
                "note": note,
                "extra_mb": peak_mb,
            }
        except TimeLimitError:
            entry = {"status": f"> {LIMIT:.0f} s (stopped)"}
        except Exception as exc:  # an anchor's own failure is a result, not a crash
            entry = {"status": f"failed: {type(exc).__name__}: {str(exc)[:70]}"}
        if method in sweep and entry.get("status") == "ok":
            entry["sweep"] = best_of(sweep[method])
        results[method] = entry
        Path(out + ".json").write_text(json.dumps(results))
    results["_maxrss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    Path(out + ".json").write_text(json.dumps(results))


def run_worker(lib: str, fam: str, tmp: str) -> dict[str, Any]:
    out = os.path.join(tmp, f"{lib}-{fam}")
    cmd = [sys.executable, __file__, "--worker", lib, fam, out]
    hard = LIMIT * len(METHODS[lib]) + 120
    env = dict(os.environ)
    blas = THREADS.get(lib, 1) if "post-decision" in lib else 1
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = str(blas)
    env["NUMBA_NUM_THREADS"] = str(THREADS.get(lib, 1))
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=hard, env=env)
        err = "" if proc.returncode == 0 else (proc.stderr.strip().splitlines() or ["?"])[-1]
    except subprocess.TimeoutExpired:
        err = f"worker stopped after {hard:.0f} s"
    data: dict[str, Any] = (
        json.loads(Path(out + ".json").read_text()) if os.path.exists(out + ".json") else {}
    )
    if err:
        data["_error"] = err[:100]
    for method, entry in data.items():
        if not method.startswith("_") and entry.get("status") == "ok":
            entry["v"] = np.load(f"{out}.{method}.v.npy")
            entry["policy"] = np.load(f"{out}.{method}.pi.npy")
    return data


def parse_args(argv: list[str]) -> Any:
    import argparse

    ap = argparse.ArgumentParser(
        prog="bench_planning.py",
        description="Exact planning on families of MDPs against quantecon and mdptoolbox-hiive "
        "(each library and family in its own subprocess); prints the tables and, unless "
        "--no-write, replaces BENCHMARKS.md's 'Exact planning' section.",
    )
    ap.add_argument(
        "--families",
        "--only",
        default="",
        help="comma-separated families to run (default: all but the --large ones): "
        + ", ".join(FAMILIES),
    )
    ap.add_argument("--large", action="store_true", help="add the families marked large")
    ap.add_argument(
        "--threads",
        default="1,2",
        help="numba threads of the policylab rows: '1', '2' or '1,2' (default 1,2)",
    )
    ap.add_argument(
        "--libs",
        default="",
        help="comma-separated libraries (default all): policylab, policylab-post-decision, "
        "quantecon, mdptoolbox-hiive",
    )
    ap.add_argument("--limit", type=float, default=LIMIT, help="seconds per method (default 30)")
    ap.add_argument("--no-write", action="store_true", help="print only; leave BENCHMARKS.md")
    ap.add_argument("--list", action="store_true", help="list the families and exit")
    ap.add_argument(
        "--scaling",
        type=int,
        default=0,
        metavar="ROUNDS",
        help="instead of the suite: auto on 1 thread pinned to core 0 against 2 threads on "
        "both cores, alternating in one process for ROUNDS rounds per family (default "
        "families: grid-0.99, grid-0.999, shortest-path, chain-0.999, inventory, "
        "jacks-car-rental); prints wall and CPU times",
    )
    args = ap.parse_args(argv)
    fams = [f for f in args.families.split(",") if f]
    bad = [f for f in fams if f not in FAMILIES]
    if bad:
        ap.error(f"unknown families {', '.join(bad)}; choose from {', '.join(FAMILIES)}")
    threads = {t for t in args.threads.split(",") if t}
    if not threads or not threads <= {"1", "2"}:
        ap.error(f"--threads takes 1, 2 or 1,2; got {args.threads!r}")
    libs = {x.replace("-post-decision", " post-decision") for x in args.libs.split(",") if x}
    known = {"policylab", "policylab post-decision", "quantecon", "mdptoolbox-hiive"}
    if not libs <= known:
        ap.error(f"unknown libraries {', '.join(sorted(libs - known))}")
    default = (
        SCALING_FAMILIES if args.scaling else [f for f in FAMILIES if args.large or f not in LARGE]
    )
    args.fams = fams or default
    args.lib_list = [
        lib
        for lib in METHODS
        if (not libs or lib.split(",")[0] in libs)
        and (
            ("2" in threads)
            if lib.endswith("2 threads")
            else ("1" in threads or not lib.startswith("policylab"))
        )
    ]
    return args


#: The families of ``--scaling``: those whose auto runs in tens of milliseconds or less.
SCALING_FAMILIES = [
    "grid-0.99",
    "grid-0.999",
    "shortest-path",
    "chain-0.999",
    "inventory",
    "jacks-car-rental",
]


def scaling(fams: list[str], rounds: int) -> str:
    """auto on 1 thread on core 0 against 2 threads on both cores, alternating in one process.

    Each round solves once with ``numba.set_num_threads(1)`` and the process pinned to
    core 0 (``os.sched_setaffinity``, as ``taskset -c 0`` would), then once with 2
    threads on both cores; the thread pool is started on both cores first, by
    policylab (``policylab.planning._kernels.num_threads``). Wall time
    (``time.perf_counter``) and the process's CPU time (``time.process_time``, all its
    threads) of every solve; the table gives the median and the fastest of each.
    """
    import numba

    from policylab.planning import solve
    from policylab.planning._kernels import num_threads

    num_threads()  # numba's threads started as policylab starts them (see its docstring)
    both = os.sched_getaffinity(0)
    lines = [
        "| family | auto's method | 1 thread, core 0: median / best wall ms | "
        "2 threads: median / best wall ms | speed-up (median, best) | CPU ms 1 / 2 threads "
        "(median) |",
        "|---|---|---:|---:|---:|---:|",
    ]
    for fam in fams:
        # the model auto is best on: the post-decision one where the family has it
        model = POST_DECISION[fam]() if fam in POST_DECISION else FAMILIES[fam][1]()
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        solve(model, tol=1e-6)  # compile, and start the thread pool on both cores
        wall: dict[int, list[float]] = {1: [], 2: []}
        cpu: dict[int, list[float]] = {1: [], 2: []}
        method = ""
        for _ in range(rounds):
            for threads in (1, 2):
                os.sched_setaffinity(0, {min(both)} if threads == 1 else both)
                numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
                forget(model)
                c0, t0 = time.process_time(), time.perf_counter()
                res = solve(model, tol=1e-6)
                wall[threads].append(time.perf_counter() - t0)
                cpu[threads].append(time.process_time() - c0)
                method = res.info["auto"]["method"]
        os.sched_setaffinity(0, both)
        m1, m2 = np.median(wall[1]), np.median(wall[2])
        b1, b2 = min(wall[1]), min(wall[2])
        lines.append(
            f"| {fam} | {method} | {m1 * 1e3:.2f} / {b1 * 1e3:.2f} | {m2 * 1e3:.2f} / "
            f"{b2 * 1e3:.2f} | {m1 / m2:.2f}x, {b1 / b2:.2f}x | "
            f"{np.median(cpu[1]) * 1e3:.2f} / {np.median(cpu[2]) * 1e3:.2f} |"
        )
        print(lines[-1], flush=True)
    return "\n".join(lines)


def reference(fam: str, table: Any, pd_model: Any) -> np.ndarray:
    """v_* of a family, proven two ways (see the module docstring)."""
    import policylab as pl
    from policylab.planning import solve

    if table is not None:
        ref = solve(table, "pi")
        check = pl.value_iteration(table, tol=1e-9, gauss_seidel=True)
    else:
        ref = solve(pd_model, "auto", tol=1e-10)
        check = solve(pd_model, "vi", tol=1e-9)
    scale = max(1.0, float(np.abs(ref.v).max()))
    assert np.max(np.abs(check.v - ref.v)) <= 1e-7 * scale, fam
    return np.asarray(ref.v)


def policy_values(table: Any, pd_model: Any, actions: np.ndarray) -> np.ndarray:
    """v_pi of a deterministic policy, exactly (the table's linear solve, or GMRES to 1e-10)."""
    import policylab as pl
    from policylab.planning import postdecision

    if table is not None:
        pi = pl.Policy.from_actions(table, np.where(table.terminal, 0, actions))
        return np.asarray(pl.evaluate_policy(table, pi))
    v, _ = postdecision.evaluate_actions(pd_model, actions.astype(np.int64), pd_model.gamma)
    return v


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2], sys.argv[3], sys.argv[4])
        return 0
    global LIMIT
    args = parse_args(sys.argv[1:])
    if args.list:
        for name, (title, _) in FAMILIES.items():
            print(f"{name:18s} {title}" + (" [--large]" if name in LARGE else ""))
        return 0
    if args.scaling:
        print(f"load average at the start: {os.getloadavg()}", flush=True)
        print(scaling(args.fams, args.scaling))
        print(f"load average at the end: {os.getloadavg()}")
        return 0
    LIMIT = args.limit
    os.environ["BENCH_PLANNING_LIMIT"] = str(LIMIT)
    from _report import load_note, write_section

    load_before = os.getloadavg()
    sections, summary = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for fam in args.fams:
            title, build = FAMILIES[fam]
            print(f"== {fam}: {title}", flush=True)
            table = build()
            pd_model = POST_DECISION[fam]() if fam in POST_DECISION else None
            shown = table if table is not None else pd_model
            v_star = reference(fam, table, pd_model)
            rows = []
            for lib in args.lib_list:
                print(f"   {lib} ...", flush=True)
                data = run_worker(lib, fam, tmp)
                for method in METHODS[lib]:
                    r = data.get(method)
                    if r is None:
                        r = {
                            "status": data.get("_skip")
                            or (
                                f"stopped ({data['_error']}, in compiled code past the alarm)"
                                if "_error" in data
                                else "not run"
                            )
                        }
                    elif r["status"] == "ok":
                        v_pi = policy_values(table, pd_model, r["policy"])
                        live = ~shown.terminal
                        r["policy_error"] = float(np.max((v_star - v_pi)[live]))
                        r["value_error"] = float(np.max(np.abs(r["v"] - v_star)[live]))
                    print(f"      {method}: {r.get('seconds', r['status'])}", flush=True)
                    rows.append((lib, method, r, data))
                    if "_skip" in data:
                        break
            sec, summ = table_of(fam, title, table, pd_model, rows)
            sections.append(sec)
            summary.append(summ)
            del table, pd_model, shown
    load_after = os.getloadavg()
    head = [
        "| family | policylab best | policylab auto (its choice) | quantecon best | "
        "speed-up of auto over quantecon's best | auto on 2 threads (speed-up over 1) | "
        "auto's peak extra memory, MiB (x model) | mdptoolbox-hiive best |",
        "|---|---|---|---|---:|---|---:|---|",
        *summary,
    ]
    load = (
        f"Load average (1, 5, 15 min) at the start: {load_before[0]:.1f}, {load_before[1]:.1f}, "
        f"{load_before[2]:.1f}; at the end: {load_after[0]:.1f}, {load_after[1]:.1f}, "
        f"{load_after[2]:.1f}. {load_note(load_before[0], load_after[0])}"
    )
    body = "\n".join(head) + "\n\n" + load + "\n\n" + "\n\n".join(sections) + "\n\n" + NOTES
    cmd = "python benchmarks/bench_planning.py" + " ".join(
        [""]
        + (["--large"] if args.large else [])
        + ([f"--families {args.families}"] if args.families else [])
        + ([f"--threads {args.threads}"] if args.threads != "1,2" else [])
        + ([f"--libs {args.libs}"] if args.libs else [])
        + ([f"--limit {args.limit:g}"] if args.limit != 30 else [])
    )
    if not args.no_write:
        write_section("Exact planning", cmd, body)
    print(body)
    return 0


def _best(rows: list[tuple[str, str, dict[str, Any], Any]], lib: str) -> tuple[float, str] | None:
    ok = [
        (r["seconds"], method_name(lb, m) + (" (post-decision)" if "decision" in lb else ""))
        for lb, m, r, _ in rows
        if lb == lib and r["status"] == "ok" and m != "auto" and r["policy_error"] <= TARGET
    ]
    return min(ok) if ok else None


def memory(r: dict[str, Any], data: dict[str, Any]) -> str:
    """A row's peak extra memory in MiB and as a multiple of its model's size."""
    return f"{r['extra_mb']:,.1f} ({r['extra_mb'] / data['_model_mb']:.2f}x)"


def table_of(
    fam: str,
    title: str,
    mdp: Any,
    pd_model: Any,
    rows: list[tuple[str, str, dict[str, Any], Any]],
) -> tuple[str, str]:
    shown = mdp if mdp is not None else pd_model
    sizes = f"{shown.n_states:,} states, {shown.n_outcomes:,} outcomes"
    if mdp is not None:
        sizes += f", outcome table {mdp.nbytes / 2**20:,.1f} MiB"
    else:
        sizes += f" (no outcome table: {NO_TABLE.get(fam, '')})"
    if pd_model is not None:
        sizes += f", post-decision model {pd_model.nbytes / 2**20:,.2f} MiB"
    lines = [
        f"### {fam}: {title}",
        "",
        sizes + ".",
        "",
        "| library | method | time (s) | iterations | one sweep / floor | max abs(v - v*) | "
        "max v* - v_pi | within 1e-6 | peak extra memory, MiB (x model) |",
        "|---|---|---:|---:|---:|---:|---:|:---:|---:|",
    ]
    first = None
    for lib, method, r, data in rows:
        if lib == "policylab" and data.get("_first") is not None:
            first = data["_first"]
        if r["status"] != "ok":
            lines.append(f"| {lib} | {method_name(lib, method)} | {r['status']} | | | | | | |")
            continue
        sweep = f"{r['sweep'] / data['_floor']:.2f}x" if r.get("sweep") else ""
        ok = r["policy_error"] <= TARGET
        name = method_name(lib, method) + (f" (chose {r['note']})" if r.get("note") else "")
        lines.append(
            f"| {lib} | {name} | {r['seconds']:.3g} | {r['iterations']} | {sweep} | "
            f"{r['value_error']:.1e} | {r['policy_error']:.1e} | {'yes' if ok else '**no**'} | "
            f"{memory(r, data)} |"
        )
    if first is not None:
        lines += ["", f"policylab's first compiled call in a fresh process: {first:.2f} s."]
    ours = min(
        (b for b in (_best(rows, "policylab"), _best(rows, "policylab post-decision")) if b),
        default=None,
    )
    qe, hv = _best(rows, "quantecon"), _best(rows, "mdptoolbox-hiive")

    def auto_of(lib: str) -> dict[str, Any] | None:
        return next(
            (r for lb, m, r, _ in rows if lb == lib and m == "auto" and r["status"] == "ok"),
            None,
        )

    pd = any(lb.startswith("policylab post-decision") for lb, *_ in rows)
    one, two_lib = (
        ("policylab post-decision", "policylab post-decision, 2 threads")
        if pd and auto_of("policylab post-decision") is not None
        else ("policylab", "policylab, 2 threads")
    )
    auto, auto2 = auto_of(one), auto_of(two_lib)
    auto_data = next((d for lb, m, _, d in rows if lb == one and m == "auto"), None)

    def fmt(b: tuple[float, str] | None) -> str:
        return "none within 1e-6" if b is None else f"{b[1]}, {b[0]:.3g} s"

    auto_s = (
        "failed"
        if auto is None
        else f"{auto['seconds']:.3g} s ({auto['note']}"
        + (", post-decision model)" if one.endswith("decision") else ")")
    )
    speed = ""
    if auto is not None and qe is not None:
        speed = f"{qe[0] / auto['seconds']:.1f}x"
    two = ""
    if auto is not None and auto2 is not None:
        two = f"{auto2['seconds']:.3g} s ({auto['seconds'] / auto2['seconds']:.2f}x)"
    mem = "" if auto is None or auto_data is None else memory(auto, auto_data)
    summ = f"| {fam} | {fmt(ours)} | {auto_s} | {fmt(qe)} | {speed} | {two} | {mem} | {fmt(hv)} |"
    return "\n".join(lines), summ


NOTES = """Notes.
- Time is the solve alone (input conversion excluded; solves under 0.5 s: the best of
  up to 5 runs), best method chosen after the
  fact (among those whose policy is within 1e-6 of optimal); "auto" is policylab's
  own choice made before solving. Each library was asked for 1e-6 (policylab: tol on
  v, with a proven bound where gamma < 1; quantecon and hiive: epsilon). "> N s
  (stopped)" means the method hit the time limit (`--limit`). Every worker holds BLAS
  and OpenMP to one thread; the "policylab" rows run numba on 1 thread, the
  "policylab, 2 threads" rows on 2. Synchronous sweeps, policy evaluation sweeps
  and the post-decision product K v of a sparse kernel use threads from 2,000,000
  outcomes (or kernel entries); ordered Gauss-Seidel sweeps and the greedy policy
  from 100,000 (the grids: the sweep is split into 2 blocks of states, Gauss-Seidel
  inside each and Jacobi between them, the same split and numbers on 1 and 2
  threads). Below those sizes, and for the back-substitution by components (policy
  iteration on the shortest path and the inventories), both rows run the same
  sequential code, so auto on 2 threads differs from 1 thread only by noise there.
  `--scaling ROUNDS` times auto alone on 1 thread pinned to one core against 2
  threads, alternating in one process.
- "peak extra memory": the memory a solve adds above what the worker held before it
  (the model, converted for the library), the larger of the peak of the arrays it
  allocates from Python (tracemalloc, on one more untimed run of each solve of at
  most 5 s) and its resident-memory samples (every 2 ms); in MiB and as a multiple of
  the size of the model that the row's library was given (the outcome table, or the
  post-decision model). Arrays allocated inside numba kernels are seen by the RSS
  samples only.
- Each policylab method finds the model's shared rows and its states' distances to
  the terminal states itself (the caches are cleared before each run), so its time
  includes those passes over the outcome table.
- "one sweep / floor": the fastest of 7 synchronous Bellman optimality sweeps over
  the fastest of 7 bare scipy CSR products P @ v with the (S * A, S) matrix, both in
  the same worker process. Where rows repeat (inventory, Jack's car rental) the sweep
  sums each distinct row once, so it runs below the floor of the full product.
- Errors: "max abs(v - v*)" is the returned values' error over non-terminal states;
  "max v* - v_pi" the returned policy's, by an exact evaluation. The reference v_*
  is policy iteration with exact evaluation, cross-checked by ordered Gauss-Seidel
  sweeps at 1e-9.
- Terminal states are given to quantecon and hiive as absorbing zero-reward states.
  quantecon disables its infinite-horizon methods at gamma = 1; hiive's solvers need
  every action available in every state, so the inventory and Jack's car rental
  families (whose A(s) depend on the state) are not run there.
- The machine is shared: other developers' jobs run at the same time (the load
  average above), so timings carry noise of tens of percent, and the 2-thread rows
  measure mostly the wait for a second core that other jobs hold (a threaded sweep
  waits for its slowest thread); they are no measure of scaling on a quiet machine.
- What wins where (the rules of `method="auto"`, see `policylab.planning.auto`):
  on episodic tasks with gamma < 1, in-place sweeps ordered from the terminal states
  backwards, started from a lower bound of v_* and solving each self-loop exactly,
  finish in 2 sweeps where synchronous sweeps need one per step of the longest path
  (about 480 on the grids, 11,000 on the chain); at gamma = 1, policy iteration from
  a proper policy, whose evaluation is an exact back-substitution when the policy's
  graph has no cycle besides self-loops (as on these grids: no matrix, no fill-in);
  on continuing tasks whose (state, action) rows repeat (the inventory's next stock
  depends on stock + order, Jack's cars on the counts after the move: 152 and 442
  distinct rows, one of them the empty row of unavailable actions, for the 22,801
  and 4,851 (state, action) slots), modified policy iteration with adaptive m on
  the distinct rows (on the post-decision model of an inventory, policy iteration:
  see the post-decision notes); other continuing tasks, policy iteration up to 5,000 states
  (a dense LU where the dense matrix is no larger than the model) and
  MacQueen-bounded value iteration above.
- Post-decision rows ("policylab post-decision"): the same MDP given to policylab as
  a `PostDecisionMDP` (`jacks_car_rental(..., post_decision=True)`,
  `inventory_management(..., post_decision=True)`): the action moves the state
  surely to the stock after the order / the cars after the move, and a kernel that
  does not depend on the action (demand; rentals and returns, a Kronecker product of
  the two locations' kernels) moves it on. A backup is one product K v plus an
  (S, A) maximum. auto: policy iteration when the kernel is one sparse matrix and
  the first policy's graph splits into small strongly connected components (the
  inventory: orders cycle only through low stock levels; 9 states at most here), as
  each exact evaluation is then a back-substitution between the components and a
  small dense LU for each; modified policy iteration with adaptive m otherwise
  (Jack's car rental, whose Kronecker kernel mixes all states). Their "one sweep /
  floor" is the backup over the bare product K v
  (BLAS matrix products for Jack's, a sparse product for the inventory); their
  2-thread rows run both numba and BLAS on 2 threads. Their model arrays are built
  in memory before timing, as the outcome tables are for the other libraries; the
  families without a table (`jacks-1e5`, and the `--large` `inventory-1e5` and
  `jacks-1e6`) have no anchor that can hold them: the table is given in the family's
  heading. Their reference v_* is policylab's auto on the post-decision model to
  1e-10 (exact policy iteration by components on the inventories, modified policy
  iteration to a proven 1e-10 on Jack's), cross-checked by value iteration at 1e-9,
  and each returned policy is evaluated exactly on the post-decision model (by
  components where its graph splits into small ones, else by GMRES to a residual
  bound of 1e-10 relative to the value scale).
- The synchronous sweep of value iteration on the outcome table is one pass that
  takes each state's maximum as its rows are summed (-inf folded into r(s, a): no
  mask read, no (S, A) temporary; each row's end read once, as the next row's
  start); the floor is scipy's CSR product with int32 row
  offsets, where the outcome table keeps int64 ones (any size of table).
- Families `inventory-1000` and `jacks-30` are the largest sizes whose outcome table
  is built here for the anchors (about 10^7 outcomes); `inventory-1000`'s table is
  the post-decision model's `to_finite_mdp()` (the same MDP; `from_dynamics` would
  take minutes at that size).
"""


if __name__ == "__main__":
    sys.exit(main())
