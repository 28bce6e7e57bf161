"""Exact planning on families of MDPs, against quantecon and mdptoolbox-hiive, in one run.

    python benchmarks/bench_planning.py            # the suite (a few minutes)
    python benchmarks/bench_planning.py --large    # adds 10^6-state cases (much longer)
    python benchmarks/bench_planning.py --only grid-0.99,chain-0.999

Families: random sparse (fast mixing); slippery gridworlds at gamma 0.99 and 0.999
(slow mixing); a long chain (the worst case of synchronous value iteration);
inventory management and Jack's car rental (dense rows, action sets that depend on
the state); an episodic gamma = 1 shortest path on the gridworld.

Each (library, family) runs in its own subprocess (16 GB address-space cap): it builds
the model, converts it to the library's input (not timed), warms the library up on a
small model, then runs each method in turn with a time limit, timing the solve alone
and sampling the resident memory it adds. The bare sparse matrix-vector product P @ v
over the (S * A, S) matrix (scipy CSR) is timed in the same process: the floor of any
sweep. The parent evaluates every returned policy exactly and reports its error
against v_* (policy iteration with exact evaluation, cross-checked by ordered
Gauss-Seidel sweeps at 1e-9).
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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

TARGET = 1e-6
LIMIT = 30.0  # seconds per method

FAMILIES: dict[str, tuple[str, Callable[[], Any]]] = {}


def family(name: str, title: str, large: bool = False) -> Callable[[Any], Any]:
    def deco(fn: Callable[[], Any]) -> Callable[[], Any]:
        FAMILIES[name] = (title, fn)
        if large:
            LARGE.add(name)
        return fn

    return deco


LARGE: set[str] = set()


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
    "inventory", "inventory_management(capacity 150: 151 states, up to 151 actions), gamma 0.95"
)
def _inventory() -> Any:
    from policylab.problems import inventory_management

    return inventory_management(capacity=150)


@family("jacks-car-rental", "jacks_car_rental() (441 states, 11 actions, dense rows), gamma 0.9")
def _jack() -> Any:
    from policylab.problems import jacks_car_rental

    return jacks_car_rental()


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
    "quantecon": ["vi", "mpi", "pi"],
    "mdptoolbox-hiive": ["vi", "vi-gs", "mpi", "pi"],
}
#: numba threads of each library's worker (every other library is single-threaded:
#: BLAS and OpenMP pools are held to one thread in all workers).
THREADS = {"policylab, 2 threads": 2}
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
    if ours_lib:
        small = pl.problems.random_mdp(50, 2, 3)
        pl.value_iteration(small)  # the first compiled call of a fresh process
        first = time.perf_counter() - t0
    mdp = FAMILIES[fam][1]()
    g = mdp.gamma
    S, A = mdp.n_states, mdp.n_actions
    floor = floor_seconds(mdp)
    mdp.expected_reward  # noqa: B018  (derived once per model; every library is given r(s, a))
    results: dict[str, Any] = {"_floor": floor, "_model_mb": mdp.nbytes / 2**20, "_first": first}
    runs: dict[str, Callable[[], tuple[np.ndarray, np.ndarray, int, str]]] = {}
    sweep: dict[str, Callable[[], Any]] = {}
    if ours_lib:
        from policylab.planning import _kernels, modified_policy_iteration, solve
        from policylab.planning._kernels import optimality_sweep

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
                _kernels._SHARED.pop(mdp, None)  # each method finds the shared rows itself
                res = solve(mdp, method, tol=TARGET)
                note = res.info.get("auto", {}).get("method", "")
                return res.v, res.policy.action_indices(), res.iterations, note

            return run

        runs = {m: ours(m) for m in METHODS[lib]}
        w = np.zeros(S)
        work = np.empty((S, A))
        sweep["vi"] = lambda: optimality_sweep(mdp, g, w, work)
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
            np.save(f"{out}.{method}.v.npy", np.asarray(v, dtype=float))
            np.save(f"{out}.{method}.pi.npy", np.asarray(policy).astype(np.int64))
            entry = {
                "status": "ok",
                "seconds": seconds,
                "iterations": iters,
                "note": note,
                "extra_mb": mem.extra_mb,
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
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"
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


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(sys.argv[2], sys.argv[3], sys.argv[4])
        return 0
    import policylab as pl
    from _report import write_section
    from policylab.planning import solve

    large = "--large" in sys.argv
    only = None
    if "--only" in sys.argv:
        only = set(sys.argv[sys.argv.index("--only") + 1].split(","))
    fams = [f for f in FAMILIES if (large or f not in LARGE) and (only is None or f in only)]
    load_before = os.getloadavg()
    sections, summary = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for fam in fams:
            title, build = FAMILIES[fam]
            print(f"== {fam}: {title}", flush=True)
            mdp = build()
            ref = solve(mdp, "pi")
            check = pl.value_iteration(mdp, tol=1e-9, gauss_seidel=True)
            scale = max(1.0, float(np.abs(ref.v).max()))
            assert np.max(np.abs(check.v - ref.v)) <= 1e-7 * scale, fam
            v_star = ref.v
            rows = []
            for lib in METHODS:
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
                        pi = pl.Policy.from_actions(mdp, np.where(mdp.terminal, 0, r["policy"]))
                        v_pi = pl.evaluate_policy(mdp, pi)
                        r["policy_error"] = float(np.max(v_star - v_pi))
                        r["value_error"] = float(np.max(np.abs(r["v"] - v_star)[~mdp.terminal]))
                    print(f"      {method}: {r.get('seconds', r['status'])}", flush=True)
                    rows.append((lib, method, r, data))
            sec, summ = table(fam, title, mdp, rows)
            sections.append(sec)
            summary.append(summ)
            del mdp
    load_after = os.getloadavg()
    head = [
        "| family | policylab best | policylab auto (its choice) | quantecon best | "
        "speed-up of auto over quantecon's best | auto on 2 threads (speed-up over 1) | "
        "mdptoolbox-hiive best |",
        "|---|---|---|---|---:|---|---|",
        *summary,
    ]
    load = (
        f"Load average (1, 5, 15 min) at the start: {load_before[0]:.1f}, {load_before[1]:.1f}, "
        f"{load_before[2]:.1f}; at the end: {load_after[0]:.1f}, {load_after[1]:.1f}, "
        f"{load_after[2]:.1f} (2 cores shared with other developers' jobs)."
    )
    body = "\n".join(head) + "\n\n" + load + "\n\n" + "\n\n".join(sections) + "\n\n" + NOTES
    cmd = "python benchmarks/bench_planning.py" + (" --large" if large else "")
    if only:
        cmd += " --only " + ",".join(sorted(only))
    write_section("Exact planning", cmd, body)
    print(body)
    return 0


def _best(rows: list[tuple[str, str, dict[str, Any], Any]], lib: str) -> tuple[float, str] | None:
    ok = [
        (r["seconds"], method_name(lb, m))
        for lb, m, r, _ in rows
        if lb == lib and r["status"] == "ok" and m != "auto" and r["policy_error"] <= TARGET
    ]
    return min(ok) if ok else None


def table(
    fam: str, title: str, mdp: Any, rows: list[tuple[str, str, dict[str, Any], Any]]
) -> tuple[str, str]:
    model_mb = mdp.nbytes / 2**20
    lines = [
        f"### {fam}: {title}",
        "",
        f"{mdp.n_states:,} states, {mdp.n_outcomes:,} outcomes, model {model_mb:,.1f} MiB.",
        "",
        "| library | method | time (s) | iterations | one sweep / floor | max abs(v - v*) | "
        "max v* - v_pi | within 1e-6 | solve extra RSS (MiB) |",
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
            f"{r['extra_mb']:,.0f} |"
        )
    if first is not None:
        lines += ["", f"policylab's first compiled call in a fresh process: {first:.2f} s."]
    ours, qe, hv = (
        _best(rows, "policylab"),
        _best(rows, "quantecon"),
        _best(rows, "mdptoolbox-hiive"),
    )

    def auto_of(lib: str) -> dict[str, Any] | None:
        return next(
            (r for lb, m, r, _ in rows if lb == lib and m == "auto" and r["status"] == "ok"),
            None,
        )

    auto, auto2 = auto_of("policylab"), auto_of("policylab, 2 threads")

    def fmt(b: tuple[float, str] | None) -> str:
        return "none within 1e-6" if b is None else f"{b[1]}, {b[0]:.3g} s"

    auto_s = "failed" if auto is None else f"{auto['seconds']:.3g} s ({auto['note']})"
    speed = ""
    if auto is not None and qe is not None:
        speed = f"{qe[0] / auto['seconds']:.1f}x"
    two = ""
    if auto is not None and auto2 is not None:
        two = f"{auto2['seconds']:.3g} s ({auto['seconds'] / auto2['seconds']:.2f}x)"
    summ = f"| {fam} | {fmt(ours)} | {auto_s} | {fmt(qe)} | {speed} | {two} | {fmt(hv)} |"
    return "\n".join(lines), summ


NOTES = """Notes.
- Time is the solve alone (input conversion excluded), best method chosen after the
  fact (among those whose policy is within 1e-6 of optimal); "auto" is policylab's
  own choice made before solving. Each library was asked for 1e-6 (policylab: tol on
  v, with a proven bound where gamma < 1; quantecon and hiive: epsilon). "> 30 s
  (stopped)" means the method hit the time limit. Every worker holds BLAS and OpenMP
  to one thread; the "policylab" rows run numba on 1 thread, the "policylab, 2
  threads" rows on 2 (threads are used by synchronous sweeps and policy evaluations
  on models of 2,000,000 outcomes or more; Gauss-Seidel sweeps stay sequential).
- Each policylab method finds the model's shared rows itself (the cache is cleared
  before each method), so its time includes that one pass over the outcome table.
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
  the distinct rows; other continuing tasks, policy iteration up to 5,000 states
  (a dense LU where the dense matrix is no larger than the model) and
  MacQueen-bounded value iteration above.
- Memory: the largest extra resident memory of any policylab solve is 9 MiB on the
  7.8 MiB grids (1.2x the model; policy iteration at gamma = 1 was 26 MiB with a
  sparse LU before the back-substitution), 3 MiB on Jack's car rental (35.5 MiB).
- Not reached (yet): on a machine this loaded (load average about 20 on 2 cores)
  the 2-thread rows are slower than the 1-thread ones on most families, so no core
  scaling is shown here; rerun on a quiet machine. A synchronous sweep on the
  grids and the chain (rows of 1-2 outcomes) costs about 2-3x the bare product
  here; a sweep that fuses the max over actions into the product was tried and is
  slower (about 5x the floor on the grid: its branch stalls the loads), so the
  two-pass sweep stays. On Jack's car rental the solvers are within noise of
  quantecon's modified policy iteration in this run (auto 0.4x, policylab's best
  1.0x), not 3x ahead; inventory is 4.6x ahead. Inventory and Jack's car rental run
  at their textbook sizes: their tables grow as S^3 / 3 outcomes (inventory, every
  order size) and S^2 per (state, action) (Jack's dense rows), so 10^5 states would
  need 10^14 and 10^11 outcomes, beyond any memory; the `--large` cases (10^6
  states) were not run on this loaded machine."""


if __name__ == "__main__":
    sys.exit(main())
