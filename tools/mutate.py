"""Mutation testing of policylab's equations: do the tests catch a wrong equation?

Each mutant below is one small wrong change to a line that implements an equation
(a Bellman backup, a stopping bound, a TD or Monte Carlo update, GAE, a PPO or DQN
loss, a validation rule, a checkpoint check). For every mutant the script

1. copies ``src/`` and ``tests/`` once into a scratch folder and writes the mutated file
   there (the working tree is never touched);
2. runs the tests that cover the mutated module with ``pytest -x``, with a fresh, empty
   numba cache folder (``NUMBA_CACHE_DIR``) and a fresh Hypothesis database
   (``HYPOTHESIS_STORAGE_DIRECTORY``), so that no compiled kernel and no stored example
   of an earlier run can hide the mutant;
3. counts the mutant *killed* if a test fails (or errors, or times out), *survived* if
   all pass.

The covering tests of a module are split into the tests it had before the mutation
study ("old") and the tests written for it ("new", the ``test_blind_spots.py`` files);
"new" tests run only when the old ones let the mutant survive, which gives the score
before and after them in one pass.

Usage::

    python tools/mutate.py                    # all mutants, writes MUTATION.md
    python tools/mutate.py --only T01,T02     # some mutants (MUTATION.md untouched)
    python tools/mutate.py --list             # the mutants, checked against the source

A mutant whose original text no longer occurs exactly once in its file is reported as
"stale" (the source moved on; update its text here) and left out of the score.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = "src/policylab/"


@dataclass(frozen=True)
class Group:
    """The tests that cover a module: those from before the study, and the new ones."""

    old: tuple[str, ...]
    new: tuple[str, ...]


PLANNING = Group(
    old=(
        "tests/planning/test_bellman.py",
        "tests/planning/test_evaluation.py",
        "tests/planning/test_solvers_agree.py",
    ),
    new=("tests/planning/test_blind_spots.py",),
)
MDP = Group(
    old=("tests/mdp/test_finite.py", "tests/mdp/test_returns.py", "tests/mdp/test_policy.py"),
    new=("tests/mdp/test_blind_spots.py",),
)
TD = Group(
    old=("tests/tabular/test_td_equivalence.py", "tests/tabular/test_td_reference.py"),
    new=("tests/tabular/test_blind_spots.py",),
)
MC = Group(old=("tests/tabular/test_mc.py",), new=("tests/tabular/test_blind_spots.py",))
SCHEDULES = Group(
    old=("tests/tabular/test_schedules.py", "tests/tabular/test_td_equivalence.py"),
    new=("tests/tabular/test_blind_spots.py",),
)
DEEP = Group(
    old=(
        "tests/deep/test_returns.py",
        "tests/deep/test_losses_and_normalization.py",
        "tests/deep/test_truncation.py",
        "tests/deep/test_buffers.py",
        "tests/deep/test_dqn.py::test_q_learning_targets_hand_computed",
    ),
    new=("tests/deep/test_blind_spots.py",),
)
CHECKPOINT = Group(old=("tests/deep/test_checkpoint.py",), new=("tests/deep/test_blind_spots.py",))


@dataclass(frozen=True)
class Mutant:
    """One wrong change: ``old`` (exactly once in ``path``) becomes ``new``."""

    id: str
    path: str
    old: str
    new: str
    group: Group
    what: str


M = Mutant
BELLMAN, KERNELS_P, SWEEPS = "planning/bellman.py", "planning/_kernels.py", "planning/_sweeps.py"
CONTROL, EVAL = "planning/control.py", "planning/evaluation.py"
FINITE, RETURNS = "mdp/finite.py", "mdp/returns.py"
KERN, TDK, MCK, SCHED = (
    "tabular/kernels.py",
    "tabular/td_kernels.py",
    "tabular/rules/mc.py",
    ("tabular/schedules.py"),
)
TDR = "tabular/rules/td.py"
DRET, PPO, DQN, CKPT = (
    "deep/common/returns.py",
    "deep/ppo/losses.py",
    "deep/dqn/losses.py",
    "deep/common/checkpoint.py",
)

MUTANTS: tuple[Mutant, ...] = (
    # ------------------------------------------------------------------ planning
    M(
        "P01",
        BELLMAN,
        "    vv[mdp.terminal] = 0.0\n    q = _q(mdp, vv, g)\n",
        "    q = _q(mdp, vv, g)\n",
        PLANNING,
        "T_pi v reads v on terminal states",
    ),
    M(
        "P02",
        BELLMAN,
        "    vv[mdp.terminal] = 0.0\n    return _max_q(",
        "    return _max_q(",
        PLANNING,
        "T v reads v on terminal states",
    ),
    M(
        "P03",
        BELLMAN,
        "    vv[mdp.terminal] = 0.0\n    return _q(mdp, vv, g)",
        "    return _q(mdp, vv, g)",
        PLANNING,
        "q = r + gamma P v reads v on terminal states",
    ),
    M(
        "P04",
        BELLMAN,
        "    v[mdp.terminal] = 0.0\n    return v\n\n\ndef bellman_optimality_backup",
        "    return v\n\n\ndef bellman_optimality_backup",
        PLANNING,
        "max_a q on a terminal state is not 0",
    ),
    M(
        "P05",
        BELLMAN,
        "rows = np.arange(S) * A + probs.argmax(axis=1)",
        "rows = np.arange(S) * A",
        PLANNING,
        "P_pi of a deterministic policy always takes action 0",
    ),
    M(
        "P06",
        BELLMAN,
        "(qq >= best - t * np.maximum(1.0, np.abs(best)))",
        "(qq >= best - t * np.abs(best))",
        PLANNING,
        "tie tolerance without its floor of 1",
    ),
    M(
        "P07",
        KERNELS_P,
        "q[row] = R[row] + gamma * acc if mask[row] else -np.inf",
        "q[row] = R[row] + acc if mask[row] else -np.inf",
        PLANNING,
        "q without the discount",
    ),
    M(
        "P08",
        KERNELS_P,
        "delta = max(delta, abs(best - v[s]))",
        "delta = max(delta, best - v[s])",
        PLANNING,
        "in-place VI residual signed (decreases ignored)",
    ),
    M(
        "P09",
        KERNELS_P,
        "row = s * n_actions + act[s]",
        "row = s * n_actions",
        PLANNING,
        "P_pi x always uses action 0",
    ),
    M(
        "P10",
        KERNELS_P,
        "total += w * (R[s, a] + gamma * acc)",
        "total += w * (R[s, a] + acc)",
        PLANNING,
        "Gauss-Seidel evaluation without the discount",
    ),
    M(
        "P11",
        SWEEPS,
        "k = gamma / (1.0 - gamma)",
        "k = gamma * (1.0 - gamma)",
        PLANNING,
        "MacQueen bound far too small (stops early)",
    ),
    M(
        "P12",
        SWEEPS,
        "lo, hi = min(lo, 0.0), max(hi, 0.0)",
        "lo, hi = lo, hi",
        PLANNING,
        "span bound ignores d = 0 on terminal states",
    ),
    M(
        "P13",
        SWEEPS,
        "return k * (lo + hi) / 2.0, k * (hi - lo) / 2.0",
        "return 0.0, k * (hi - lo) / 2.0",
        PLANNING,
        "midpoint shift not applied",
    ),
    M(
        "P14",
        SWEEPS,
        "bound = gamma / (1.0 - gamma) * residual",
        "bound = residual",
        PLANNING,
        "in-place stopping rule without gamma / (1 - gamma)",
    ),
    M(
        "P15",
        EVAL,
        'sp.eye_array(S, format="csr") - gamma * matrix()',
        'sp.eye_array(S, format="csr") - matrix()',
        PLANNING,
        "(I - P_pi) v = r_pi: gamma lost",
    ),
    M(
        "P16",
        EVAL,
        "return np.asarray(y - gamma * (P @ y))",
        "return np.asarray(y - (P @ y))",
        PLANNING,
        "iterative evaluation operator without gamma",
    ),
    M(
        "P17",
        CONTROL,
        "keep = cur_q >= best - tie_tol * np.maximum(1.0, np.abs(best))",
        "keep = cur_q >= best + tie_tol * np.maximum(1.0, np.abs(best))",
        PLANNING,
        "policy improvement keeps only strictly better current actions",
    ),
    # ------------------------------------------------------------------ mdp
    M(
        "M01",
        FINITE,
        "bad_term = term & (counts.sum(axis=1) > 0)",
        "bad_term = term & (counts.sum(axis=1) < 0)",
        MDP,
        "terminal dynamics accepted",
    ),
    M(
        "M02",
        FINITE,
        "bad = mask.ravel() & (np.abs(sums - 1.0) > PROB_TOL)",
        "bad = mask.ravel() & (np.abs(sums - 1.0) > 0.1)",
        MDP,
        "probabilities may sum to 0.95",
    ),
    M(
        "M03",
        FINITE,
        "np.any(probs < 0):",
        "np.any(probs < -1):",
        MDP,
        "negative probabilities accepted",
    ),
    M(
        "M04",
        FINITE,
        "unavailable = ~mask & ~term[:, None] & (counts > 0)",
        "unavailable = ~mask & ~term[:, None] & (counts > 1)",
        MDP,
        "unavailable action with one outcome accepted",
    ),
    M(
        "M05",
        FINITE,
        "no_action = ~term & ~mask.any(axis=1)",
        "no_action = ~term & ~mask.any(axis=1) & term",
        MDP,
        "state without actions accepted",
    ),
    M(
        "M06",
        FINITE,
        "if np.any(init[term] > 0):",
        "if np.any(init[term] > 1):",
        MDP,
        "start distribution on a terminal state accepted",
    ),
    M(
        "M07",
        FINITE,
        "mask = mask & ~term[:, None]\n        counts",
        "mask = mask\n        counts",
        MDP,
        "terminal rows of A(s) kept",
    ),
    M(
        "M08",
        RETURNS,
        "acc = r[t] + g * acc\n        out[t] = acc",
        "acc = r[t] + acc\n        out[t] = acc",
        MDP,
        "returns to go undiscounted",
    ),
    M(
        "M09",
        RETURNS,
        "acc = float(x) + g * acc",
        "acc = float(x) * g + acc",
        MDP,
        "G_0 discounts the wrong end",
    ),
    M("M10", RETURNS, "if not 0.0 <= g <= 1.0:", "if not 0.0 <= g:", MDP, "gamma > 1 accepted"),
    # ------------------------------------------------------------------ tabular kernels
    M(
        "T01",
        KERN,
        "p += (1.0 - epsilon) / n_best",
        "p += 1.0 - epsilon",
        TD,
        "epsilon-greedy probability ignores ties",
    ),
    M(
        "T02",
        KERN,
        "p = epsilon / n_avail",
        "p = epsilon / q_row.shape[0]",
        TD,
        "epsilon spread over unavailable actions too",
    ),
    M(
        "T03",
        KERN,
        "if epsilon > 0.0 and rand_uniform(state) < epsilon:",
        "if epsilon > 0.0 and rand_uniform(state) > epsilon:",
        TD,
        "explores with 1 - epsilon",
    ),
    M(
        "T04",
        KERN,
        "if mask_row[a] and (best < 0 or q_row[a] > best_q):",
        "if best < 0 or q_row[a] > best_q:",
        MC,
        "greedy action may be unavailable",
    ),
    M(
        "T05",
        TDR,
        "    if terminated:\n        return r\n    return r + gamma * v_next",
        "    return r + gamma * v_next",
        TD,
        "TD(0) target bootstraps past termination",
    ),
    M(
        "T06",
        TDR,
        "return estimate + alpha * (target - estimate)",
        "return estimate + alpha * (target + estimate)",
        TD,
        "TD update sign",
    ),
    M(
        "T07",
        TDR,
        "if mask[s_next, a] and q[s_next, a] > best:",
        "if q[s_next, a] > best:",
        TD,
        "Q-learning max over unavailable actions",
    ),
    M(
        "T08",
        TDR,
        "expected += epsilon_greedy_prob(q_next_row, mask_row, epsilon, a) * q_next_row[a]",
        "expected += q_next_row[a] / q_next_row.shape[0]",
        TD,
        "Expected Sarsa under the uniform policy",
    ),
    M(
        "T09",
        TDR,
        "return r + gamma * float(q_eval_row[arg])",
        "return r + gamma * float(q_select_row[arg])",
        TD,
        "Double Q values its own argmax",
    ),
    M(
        "T10",
        TDR,
        "g += p * rewards[i % m]",
        "g += rewards[i % m]",
        TD,
        "n-step return undiscounted inside",
    ),
    M(
        "T11",
        TDK,
        "bootstrap_end = not terminated",
        "bootstrap_end = False",
        TD,
        "n-step TD does not bootstrap at truncation",
    ),
    M(
        "T12",
        TDK,
        "td_update(v[s], alpha, td_target(r, gamma, v[s2], terminated))",
        "td_update(v[s], alpha, td_target(r, gamma, v[s2], terminated or t >= max_steps))",
        TD,
        "TD(0) does not bootstrap at the step limit",
    ),
    M("T13", TDK, "e[s, c] = 1.0", "e[s, c] += 1.0", TD, "replacing trace accumulates"),
    M("T14", TDK, "e[i, j] *= gamma * lam", "e[i, j] *= lam", TD, "trace decays without gamma"),
    M(
        "T15",
        TDK,
        "q_next = q1[s2, a2]",
        "q_next = q1[s2, a]",
        TD,
        "Sarsa bootstraps from the wrong action",
    ),
    M(
        "T16",
        MCK,
        "use_v = (not first_visit) or flags_v[t]",
        "use_v = True",
        MC,
        "first-visit V averages every visit",
    ),
    M(
        "T17",
        MCK,
        "use_v = (not first_visit) or flags_v[t]",
        "use_v = (not first_visit) or flags_q[t]",
        MC,
        "V uses the first visits of (s, a)",
    ),
    M(
        "T18",
        MCK,
        "        g = buf_r[t] + gamma * g\n",
        "        g = buf_r[t] + g\n",
        MC,
        "Monte Carlo return undiscounted",
    ),
    M("T19", MCK, "w_v = w * rho", "w_v = w", MC, "off-policy V misses rho_t"),
    M(
        "T20",
        MCK,
        "v[s] += (w_v * g - v[s]) / nv[s]",
        "v[s] += (w_v * g - v[s]) / (nv[s] + 1.0)",
        MC,
        "ordinary IS V divides by N + 1",
    ),
    M("T21", MCK, "cv[s] += w_v", "cv[s] += 1.0", MC, "weighted IS V sums counts, not weights"),
    M("T22", MCK, "rho = 1.0 / buf_b[t]", "rho = 1.0", MC, "off-policy control W ignores b"),
    M(
        "T23",
        MCK,
        "q[k] += (w * g - q[k]) / nq[k]",
        "q[k] += (g - q[k]) / nq[k]",
        MC,
        "ordinary IS Q ignores W",
    ),
    M(
        "T24",
        MCK,
        "        g = rewards[t] + gamma * g\n",
        "        g = rewards[t] + g\n",
        MC,
        "episode return G_0 undiscounted",
    ),
    M(
        "T25",
        SCHED,
        "return float(max(a / n**b, c))",
        "return float(max(a / n, c))",
        SCHEDULES,
        "inverse schedule ignores its power",
    ),
    M(
        "T26",
        SCHED,
        "return float(max(a * b ** (n - 1.0), c))",
        "return float(max(a * b**n, c))",
        SCHEDULES,
        "exponential schedule off by one",
    ),
    M(
        "T27",
        SCHED,
        "frac = (n - 1.0) / b",
        "frac = n / b",
        SCHEDULES,
        "linear schedule off by one",
    ),
    # ------------------------------------------------------------------ deep
    M(
        "D01",
        DRET,
        'delta = r + g * (~term) * arrays["next_values"]',
        'delta = r + g * arrays["next_values"]',
        DEEP,
        "GAE bootstraps past termination",
    ),
    M(
        "D02",
        DRET,
        "carry = g * lam * ~(term | trunc)",
        "carry = g * lam * ~term",
        DEEP,
        "GAE leaks across truncation",
    ),
    M(
        "D03",
        DRET,
        "carry = g * lam * ~(term | trunc)",
        "carry = g * ~(term | trunc)",
        DEEP,
        "GAE ignores lambda",
    ),
    M(
        "D04",
        DRET,
        "acc, (0.0 if term[k] else w), k",
        "acc, w, k",
        DEEP,
        "n-step target bootstraps past termination",
    ),
    M(
        "D05",
        DRET,
        "if done[k] or k - t + 1 == n or k == T - 1:",
        "if term[k] or k - t + 1 == n or k == T - 1:",
        DEEP,
        "n-step sum runs across truncation",
    ),
    M(
        "D06",
        PPO,
        "return -torch.min(unclipped, clipped).mean()",
        "return -torch.max(unclipped, clipped).mean()",
        DEEP,
        "PPO takes the optimistic bound",
    ),
    M(
        "D07",
        PPO,
        "torch.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range)",
        "torch.clamp(ratio, 1.0 - clip_range, 1.0 + 2.0 * clip_range)",
        DEEP,
        "PPO upper clip at 1 + 2 eps",
    ),
    M(
        "D08",
        PPO,
        "return torch.max(err, (clipped - returns) ** 2).mean()",
        "return torch.min(err, (clipped - returns) ** 2).mean()",
        DEEP,
        "value clipping uses min",
    ),
    M(
        "D09",
        PPO,
        "return (x - x.mean()) / (x.std() + eps)",
        "return x / (x.std() + eps)",
        DEEP,
        "advantage normalisation not centred",
    ),
    M(
        "D10",
        DQN,
        "bootstrap = next_q_target.gather(1, best).squeeze(1)",
        "bootstrap = next_q_online.gather(1, best).squeeze(1)",
        DEEP,
        "Double DQN values with the online net",
    ),
    M(
        "D11",
        DQN,
        "return returns + discounts * bootstrap",
        "return returns + bootstrap",
        DEEP,
        "DQN target ignores the bootstrap weight",
    ),
    M(
        "D12",
        DQN,
        'functional.smooth_l1_loss(td_errors, zeros, reduction="none")',
        "td_errors.abs()",
        DEEP,
        "Huber loss replaced by L1",
    ),
    M(
        "D13",
        DQN,
        "return (weights * per).mean()",
        "return per.mean()",
        DEEP,
        "importance weights ignored",
    ),
    M(
        "C01",
        CKPT,
        'if doc.get("version") != VERSION:',
        'if doc.get("version") is None:',
        CHECKPOINT,
        "checkpoint of another version accepted",
    ),
    M(
        "C02",
        CKPT,
        'map_location="cpu", weights_only=True',
        'map_location="cpu", weights_only=False',
        CHECKPOINT,
        "checkpoint may unpickle arbitrary objects",
    ),
    M(
        "C03",
        CKPT,
        'if not isinstance(doc, dict) or doc.get("format") != FORMAT:',
        "if not isinstance(doc, dict):",
        CHECKPOINT,
        "file without the format tag accepted",
    ),
)

#: Survivors shown to be equivalent to the original (no test can tell them apart).
EQUIVALENT: dict[str, str] = {}


def _exists(work: Path, test: str) -> bool:
    """Whether a test file (or the file of a ``file::test`` node id) is in the tree."""
    return (work / test.split("::")[0]).exists()


def check_mutants(src: Path) -> dict[str, str]:
    """For each mutant: "" if its text occurs exactly once, else why it is stale."""
    out: dict[str, str] = {}
    for m in MUTANTS:
        text = (src / PKG / m.path).read_text()
        n = text.count(m.old)
        out[m.id] = "" if n == 1 else f"original text found {n} times in {m.path}"
    return out


def run_tests(work: Path, tests: tuple[str, ...], tag: str, timeout: float) -> tuple[str, float]:
    """Run pytest -x on ``tests`` in ``work`` with a fresh numba cache and Hypothesis database.

    Returns ("pass" | "fail" | "timeout", seconds).
    """
    scratch = Path(tempfile.mkdtemp(prefix=f"mutant-{tag}-"))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "HYPOTHESIS_"))}
    env.update(
        PYTHONPATH=str(work / "src"),
        NUMBA_CACHE_DIR=str(scratch / "numba"),
        HYPOTHESIS_STORAGE_DIRECTORY=str(scratch / "hypothesis"),
        MPLBACKEND="Agg",
    )
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=work, env=env, capture_output=True, text=True, timeout=timeout
        )
        status = "pass" if proc.returncode == 0 else "fail"
        if proc.returncode not in (0, 1):  # collection error, crash: still a kill, but say so
            status = f"fail (pytest exit {proc.returncode})"
    except subprocess.TimeoutExpired:
        status = "timeout"
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return status, time.perf_counter() - t0


def prepare(work: Path) -> None:
    """Copy the sources and tests into the scratch tree (once)."""
    for name in ("src", "tests"):
        shutil.copytree(
            ROOT / name, work / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info")
        )
    shutil.copy(ROOT / "pyproject.toml", work / "pyproject.toml")


def main(argv: list[str] | None = None) -> int:
    """Run the mutants (all, or ``--only``) and write the report."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", help="comma-separated mutant ids")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--out", default=str(ROOT / "MUTATION.md"), help="report file")
    ap.add_argument("--json", default=None, help="also write the raw results here")
    ap.add_argument("--report", default=None, help="only write the report from these results")
    ap.add_argument(
        "--update",
        default=None,
        help="results (JSON of --json) of an earlier full run: the mutants run now replace "
        "theirs, and the report is written from the merged results",
    )
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per pytest run")
    args = ap.parse_args(argv)

    if args.report:
        done = json.loads(Path(args.report).read_text())
        write_report(Path(args.out), done["results"], done["runs"])
        return 0
    stale = check_mutants(ROOT)
    if args.list:
        for m in MUTANTS:
            note = f"  [STALE: {stale[m.id]}]" if stale[m.id] else ""
            print(f"{m.id}  {m.path:28s} {m.what}{note}")
        return 0
    chosen = [m for m in MUTANTS if not args.only or m.id in args.only.split(",")]
    unknown = set(args.only.split(",")) - {m.id for m in MUTANTS} if args.only else set()
    if unknown:
        print(f"unknown mutant ids: {sorted(unknown)}", file=sys.stderr)
        return 2

    # A kill (SIGTERM) still runs the clean-up of the scratch folders.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    t_start = time.perf_counter()
    results: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory(prefix="policylab-mutate-") as tmp:
        work = Path(tmp)
        prepare(work)
        groups = {g: None for g in [m.group for m in chosen]}
        all_tests = sorted({t for g in groups for t in (*g.old, *g.new) if _exists(work, t)})
        status, secs = run_tests(work, tuple(all_tests), "baseline", args.timeout)
        print(f"baseline ({len(all_tests)} test files): {status} in {secs:.0f} s", flush=True)
        if status != "pass":
            print("the unmutated tests must pass first", file=sys.stderr)
            return 1
        for m in chosen:
            row: dict[str, object] = {"id": m.id, "path": m.path, "what": m.what}
            if stale[m.id]:
                row.update(status="stale", why=stale[m.id])
                results.append(row)
                print(f"{m.id} STALE {stale[m.id]}", flush=True)
                continue
            target = work / PKG / m.path
            original = target.read_text()
            target.write_text(original.replace(m.old, m.new, 1))
            try:
                old = tuple(t for t in m.group.old if _exists(work, t))
                new = tuple(t for t in m.group.new if _exists(work, t))
                status, secs = run_tests(work, old, m.id, args.timeout)
                killed_by = "old" if status != "pass" else None
                total = secs
                if killed_by is None and new:
                    status, secs = run_tests(work, new, m.id, args.timeout)
                    total += secs
                    killed_by = "new" if status != "pass" else None
            finally:
                target.write_text(original)
            verdict = "killed" if killed_by else "survived"
            if verdict == "survived" and m.id in EQUIVALENT:
                verdict = "equivalent"
            row.update(status=verdict, killed_by=killed_by, outcome=status, seconds=round(total, 1))
            results.append(row)
            print(
                f"{m.id} {verdict:10s} {killed_by or '-':4s} {total:5.0f} s  {m.what}", flush=True
            )
    wall = time.perf_counter() - t_start
    runs = [{"mutants": len(results), "minutes": round(wall / 60, 1), "load": _load()}]
    if args.update:
        earlier = json.loads(Path(args.update).read_text())
        now = {str(r["id"]): r for r in results}
        results = [now.get(str(r["id"]), r) for r in earlier["results"]]
        runs = [*earlier["runs"], *runs]
    if args.json:
        Path(args.json).write_text(json.dumps({"results": results, "runs": runs}, indent=1))
    if not args.only or args.update:
        write_report(Path(args.out), results, runs)
    summary = score(results)
    print(
        f"score before the new tests {summary['before']}, after {summary['after']}; "
        f"{wall / 60:.1f} min"
    )
    return 0


def score(results: list[dict[str, object]]) -> dict[str, str]:
    """Killed / counted mutants, by the old tests and by old and new tests together."""
    live = [r for r in results if r["status"] != "stale"]
    counted = [r for r in live if r["status"] != "equivalent"]
    old = sum(1 for r in counted if r.get("killed_by") == "old")
    both = sum(1 for r in counted if r.get("killed_by") in ("old", "new"))
    n = len(counted)

    def pct(k: int) -> str:
        return f"{k}/{n} ({100.0 * k / n:.1f}%)" if n else "0/0"

    return {"before": pct(old), "after": pct(both), "n": str(n)}


def _load() -> str:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return ", ".join(f"{x:.1f}" for x in load)


def write_report(
    path: Path, results: list[dict[str, object]], runs: list[dict[str, object]]
) -> None:
    """MUTATION.md: the score, the run time and load, every mutant, the survivors."""
    s = score(results)
    by_id = {m.id: m for m in MUTANTS}
    lines = [
        "# Mutation testing",
        "",
        "Each mutant is one small wrong change to a line that implements an equation; a",
        "mutant is killed when the tests covering its module fail. Every mutant runs with an",
        "empty numba cache folder and an empty Hypothesis database. Generated by",
        "`make mutate` (`python tools/mutate.py`); the mutants and their tests are listed",
        "in `tools/mutate.py`.",
        "",
        f"- Mutants: {len(results)} ({s['n']} counted; equivalent and stale ones left out)",
        f"- Killed by the tests that existed before this study: **{s['before']}**",
        f"- Killed with the new tests (`test_blind_spots.py` files): **{s['after']}**",
        f"- Machine: {os.cpu_count()} cores, Python {platform.python_version()}, shared with"
        " other jobs; run time (with the load average at the end of each run):",
        *[f"  - {r['mutants']} mutants: {r['minutes']} min (load {r['load']})" for r in runs],
        "",
        '"Old" means the covering test files of the mutant\'s module that existed before',
        'this study (listed per module in `tools/mutate.py`), not the whole suite; "new" the',
        "`test_blind_spots.py` files, run only when the old tests let a mutant live.",
    ]
    if len(runs) > 1:
        lines += [
            "Runs after the first re-ran (`--only ... --update`) the mutants that had survived",
            "it, with the tests written since; the other rows are the first run's.",
        ]
    lines += [
        "",
        "| id | file | wrong change | result | killed by | seconds |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['id']} | `{r['path']}` | {r['what']} | {r['status']} | "
            f"{r.get('killed_by') or '-'} | {r.get('seconds', '-')} |"
        )
    survivors = [r for r in results if r["status"] == "survived"]
    equivalent = [r for r in results if r["status"] == "equivalent"]
    lines += ["", "## Survivors", ""]
    if survivors:
        for r in survivors:
            m = by_id[str(r["id"])]
            lines.append(f"- {m.id} `{m.path}`: `{m.old.strip()}` -> `{m.new.strip()}` ({m.what})")
    else:
        lines.append("None.")
    lines += ["", "## Equivalent mutants", ""]
    if equivalent:
        for r in equivalent:
            m = by_id[str(r["id"])]
            lines.append(f"- {m.id} `{m.path}` ({m.what}): {EQUIVALENT[m.id]}")
    else:
        lines.append("None.")
    stale = [r for r in results if r["status"] == "stale"]
    if stale:
        lines += ["", "## Stale mutants (source changed; update `tools/mutate.py`)", ""]
        lines += [f"- {r['id']}: {r['why']}" for r in stale]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
