"""One driver for every built-in tabular learner, Monte Carlo and TD alike.

A learner call goes in two steps, the same for every algorithm:

1. its **entry** (a ``TDEntry`` in ``td``, an ``MCEntry`` in ``mc``) turns the call's
   arguments into a :class:`Plan`: the options checked, the problem resolved, what the
   exact answer is, and how to start one run (:attr:`Plan.start`) or many at once
   (:attr:`Plan.many`);
2. :func:`learn` runs a plan for one seed: ground truth, seeding, the kernel called
   chunk by chunk between checkpoints with a progress bar, the error recorded, and the
   :class:`~policylab.tabular.LearnResult`; :func:`seed_study` runs it for many seeds
   in one parallel compiled call.

The options every learner shares are :class:`LearnOptions` (one convention, documented
once); a learner's public function takes them as ``**options``.
"""

from __future__ import annotations

import contextlib
import inspect
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, TypedDict

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.tabular.common import (
    Recorder,
    check_count,
    check_episodes,
    checkpoint_episodes,
    is_finite_mdp,
    progress_bar,
)
from policylab.tabular.kernels import rng_states, seed_states
from policylab.tabular.registry import list_algorithms
from policylab.tabular.result import LearnResult
from policylab.validation import as_generator, check_seed, did_you_mean, normalize_name

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.tabular.truth import GroundTruth

__all__ = ["LEARN_DEFAULTS", "LearnOptions", "Plan", "SeedRuns", "learn", "seed_study"]

Seed = int | np.random.Generator | None


class LearnOptions(TypedDict, total=False):
    """The keyword options every tabular learner takes (Monte Carlo and TD).

    Attributes:
        gamma: Discount rate in [0, 1] (default None: the problem's own).
        seed: Seed or Generator (default None); same seed, same result.
        checkpoints: About how many points of the error curve against the exact
            answer, log-spaced over the episodes (default 50).
        max_steps: Step limit of an episode (default 10,000); TD bootstraps from the
            last state of a truncated episode, Monte Carlo does not use it (it needs
            complete episodes; see ``result.truncated``).
        model: The exact FiniteMDP behind a Gymnasium env, for the error curve
            (default None: the env's own model, if it has one).
        progress: Show a progress bar (default False).
    """

    gamma: float | None
    seed: Seed
    checkpoints: int
    max_steps: int
    model: FiniteMDP | None
    progress: bool


#: The default of each :class:`LearnOptions` key.
LEARN_DEFAULTS: dict[str, Any] = {
    "gamma": None,
    "seed": None,
    "checkpoints": 50,
    "max_steps": 10_000,
    "model": None,
    "progress": False,
}


def call_args(name: str, args: dict[str, Any]) -> dict[str, Any]:
    """A public learner's arguments (its ``locals()``) with ``**options`` filled in.

    Raises:
        InvalidArgumentError: Naming an unknown keyword.
    """
    args = dict(args)
    options = args.pop("options", {})
    unknown = sorted(set(options) - set(LEARN_DEFAULTS))
    if unknown:
        raise InvalidArgumentError(
            f"{name}: unknown options {unknown}; the shared ones are {sorted(LEARN_DEFAULTS)}"
        )
    return {**LEARN_DEFAULTS, **options, **args}


class Run(Protocol):
    """One run of a plan, started with its RNG state: what the driver calls."""

    def __call__(self, k0: int, k1: int) -> int:
        """Run episodes k0 .. k1 - 1; return the environment steps taken."""

    def estimate(self) -> tuple[Any, Any, Any]:
        """(Q or None, V or None, states seen or None): what the error is measured on."""

    def outcome(self) -> dict[str, Any]:
        """The run's own :class:`LearnResult` fields (tables, policy, episode records)."""


class Many(NamedTuple):
    """R runs of a plan in one call, stacked (leading run axis)."""

    returns: Any
    lengths: Any
    q: Any
    v: Any
    first_actions: Any
    steps: int


@dataclass(frozen=True)
class Plan:
    """A learner call checked and set up, not yet run.

    Attributes:
        algorithm: The registry name.
        problem: The problem's name.
        mdp: The exact model, if known.
        episodes: Episodes per run.
        checkpoints: Episode counts at which the error is recorded.
        gamma: The discount used.
        params: The result's ``params`` (the settings, as recorded).
        truth: Computes the exact answer to score against (None: not scored).
        start: ``start(rng, generator)``: a fresh run with its kernel RNG state (the
            generator it came from seeds an env where there is one).
        many: ``many(rngs)``: one run per RNG state in one parallel compiled call
            (None where the runs cannot be batched: a Gymnasium env).
        compiled: Whether the run is the compiled path (else over a Gymnasium env).
    """

    algorithm: str
    problem: str
    mdp: FiniteMDP | None
    episodes: int
    checkpoints: NDArray[np.int64]
    gamma: float
    params: dict[str, Any]
    truth: Callable[[], GroundTruth | None]
    start: Callable[[NDArray[np.uint64], np.random.Generator], Run]
    many: Callable[[NDArray[np.uint64]], Many] | None
    compiled: bool


def check_shared(args: dict[str, Any]) -> tuple[int, int, NDArray[np.int64]]:
    """(episodes, max_steps, checkpoint episodes) of a call, checked."""
    episodes = check_episodes(args["episodes"])
    max_steps = check_episodes(args["max_steps"], "max_steps")
    return episodes, max_steps, checkpoint_episodes(episodes, args["checkpoints"])


def learn(plan: Plan, seed: Seed, progress: bool = False) -> LearnResult:
    """Run ``plan`` once: seeding, chunks between checkpoints, the error, the result."""
    rec = Recorder(plan.truth(), plan.checkpoints)
    gen = as_generator(seed)
    run = plan.start(rng_states(gen, 1)[0], gen)
    steps = 0
    t0 = time.perf_counter()
    with progress_bar(progress, plan.episodes, plan.algorithm) as advance:
        for k0, k1 in rec.chunks():
            steps += run(k0, k1)
            rec.record(*run.estimate())
            advance(k1 - k0)
    seconds = time.perf_counter() - t0
    return LearnResult(
        algorithm=plan.algorithm,
        problem=plan.problem,
        episodes=plan.episodes,
        steps=int(steps),
        seconds=seconds,
        params={
            **plan.params,
            "gamma": plan.gamma,
            "seed": seed if isinstance(seed, int | np.integer) else None,
            "path": "compiled" if plan.compiled else "gymnasium",
        },
        mdp=plan.mdp,
        **run.outcome(),
        **rec.arrays(),
    )


# =============================================================================== the entries
class Entry(Protocol):
    """What a built-in algorithm's entry gives the driver: its plan from a call's arguments."""

    @property
    def name(self) -> str:
        """The registry name."""

    def plan(self, args: dict[str, Any]) -> Plan:
        """The :class:`Plan` of a call with these arguments (all keywords filled in)."""


#: The built-in algorithms' entries by registry name (TD and Monte Carlo).
ENTRIES: dict[str, Entry] = {}


def add_entries(entries: Sequence[Entry]) -> None:
    """Make entries known to :func:`learn_entry` and :func:`seed_study`."""
    for entry in entries:
        ENTRIES[entry.name] = entry


def learn_entry(name: str, args: dict[str, Any]) -> LearnResult:
    """Run the learner of entry ``name`` with a public function's arguments (its locals)."""
    full = call_args(name, args)
    return learn(ENTRIES[name].plan(full), full["seed"], full["progress"])


# =============================================================================== many seeds
@dataclass
class SeedRuns:
    """One learner run for many seeds (independent runs), as arrays with a leading run axis.

    Attributes:
        algorithm: The learner's registry name.
        problem: The problem's name.
        seeds: Number of runs R.
        returns: (R, episodes) the return G_0 of every episode of every run.
        lengths: (R, episodes) the steps of every episode (0 where a learner added by
            hand does not record them).
        q: (R, S, A) the final Q of each run (as the learner's result gives it).
        v: (R, S) the final V of each run.
        first_actions: (R, episodes) A_0 of every episode (one-step control), else None.
        steps: Environment steps over all runs.
        seconds: Wall-clock time of the runs.
    """

    algorithm: str
    problem: str
    seeds: int
    returns: NDArray[np.float64]
    lengths: NDArray[np.int64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    first_actions: NDArray[np.int64] | None
    steps: int
    seconds: float

    def mean_return(self, first: int = 0, last: int | None = None) -> float:
        """Mean return per episode over episodes ``first .. last - 1`` and all runs."""
        return float(self.returns[:, first:last].mean())


#: A learner's keywords that :func:`seed_study` sets itself.
_SET_BY_STUDY = {"problem", "episodes", "seed", "checkpoints", "progress", "policy"}
_KEYWORDS = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def _keywords(learner: Callable[..., Any]) -> dict[str, Any]:
    """A learner's keyword parameters and their defaults (with the shared ``**options``)."""
    out: dict[str, Any] = {}
    for p in inspect.signature(learner).parameters.values():
        if p.kind in _KEYWORDS:
            out[p.name] = p.default
        elif p.kind is inspect.Parameter.VAR_KEYWORD and p.name == "options":
            out.update(LEARN_DEFAULTS)
    return out


def seed_study(
    algorithm: str,
    problem: FiniteMDP | Any,
    seeds: int | Sequence[int] = 100,
    *,
    seed: Seed = 0,
    episodes: int = 500,
    policy: Any = None,
    workers: int | None = None,
    **options: Any,
) -> SeedRuns:
    """Run a tabular learner for many seeds independently, in one compiled call.

    Run r is exactly ``learner(problem, seed=seeds[r], episodes=episodes, **options)``
    alone (same returns, lengths, tables, bit for bit), for every registered algorithm
    (TD and Monte Carlo). ``seeds`` is either the list of seeds, or a number R of runs
    whose seeds are drawn from ``seed``
    (``numpy.random.default_rng(seed).integers(2**63 - 1, size=R)``). On a FiniteMDP
    all runs go in one call of a compiled loop parallel over runs (numba ``prange``:
    each run has its own tables and its own RNG stream, so the numbers do not depend on
    the number of threads, see ``numba.set_num_threads``); on a Gymnasium env, or for a
    learner registered by hand, the runs go one after the other. The per-run results
    are stacked into the arrays the book's figures average: every episode's return,
    length and first action of every run.

    Args:
        algorithm: A registered algorithm's name (``"sarsa"``, ``"mc-control"``, ...).
        problem: A FiniteMDP (one parallel compiled call for the built-in algorithms)
            or a Gymnasium env with discrete observations (runs one after the other).
        seeds: The seeds of the runs, or their number.
        seed: Seed from which the runs' seeds are drawn when ``seeds`` is a number.
        episodes: Episodes per run.
        policy: The policy evaluated (prediction methods).
        workers: Most threads to run on (default: numba's, the number of CPUs).
        **options: The learner's own keyword arguments (``alpha``, ``epsilon``, ``n``,
            ``lam``, ``trace``, ``planning_steps``, ``gamma``, ``max_steps``, ``init``, ...).

    Returns:
        A :class:`SeedRuns`.
    """
    name = normalize_name(algorithm)
    known = {spec.name: spec for spec in list_algorithms()}
    if name not in known:
        raise InvalidArgumentError(
            f"unknown TD algorithm {algorithm!r} (nor a Monte Carlo one)"
            f"{did_you_mean(name, known)}; known: {', '.join(sorted(known))}"
        )
    learner = known[name].learner
    keywords = _keywords(learner)
    unknown = sorted(set(options) - (set(keywords) - _SET_BY_STUDY))
    if unknown:
        raise InvalidArgumentError(f"{name}: unknown options {unknown}")
    takes_policy = "policy" in keywords
    if not takes_policy and policy is not None:
        raise InvalidArgumentError(f"{name} is a control method; it takes no policy")
    seed_list = _seed_list(seeds, seed)
    kwargs = dict(options, episodes=episodes, checkpoints=1)
    if takes_policy:
        kwargs["policy"] = policy
    t0 = time.perf_counter()
    plan = None
    if name in ENTRIES and is_finite_mdp(problem):
        args = {**keywords, **kwargs, "problem": problem, "progress": False}
        plan = ENTRIES[name].plan(args)
    if plan is None or plan.many is None:  # one run at a time (an env, a learner by hand)
        results = [learner(problem, seed=s, **kwargs) for s in seed_list]
        first = [r.first_actions for r in results]
        return SeedRuns(
            name,
            results[0].problem,
            len(seed_list),
            np.stack([r.episode_returns for r in results]),
            np.stack([_lengths(r) for r in results]),
            np.stack([r.q for r in results]),
            np.stack([r.v if r.v is not None else r.q.max(axis=1) for r in results]),
            None if any(f is None for f in first) else np.stack(first),  # type: ignore[arg-type]
            sum(r.steps for r in results),
            time.perf_counter() - t0,
        )
    with _threads(workers):
        many = plan.many(seed_states(seed_list))
    return SeedRuns(
        name,
        plan.problem,
        len(seed_list),
        many.returns,
        many.lengths,
        many.q,
        many.v,
        many.first_actions,
        int(many.steps),
        time.perf_counter() - t0,
    )


def _lengths(res: LearnResult) -> NDArray[np.int64]:
    """A result's episode lengths (zeros where its learner does not record them)."""
    if res.episode_lengths is None:
        return np.zeros(len(res.episode_returns), dtype=np.int64)
    return res.episode_lengths


def _seed_list(seeds: int | Sequence[int], seed: Seed) -> list[int]:
    """The runs' seeds: the list given (each checked), or R seeds drawn from ``seed``."""
    if isinstance(seeds, int | np.integer) and not isinstance(seeds, bool):
        n_runs = check_episodes(seeds, "seeds")
        return [int(x) for x in as_generator(seed).integers(2**63 - 1, size=n_runs)]
    if isinstance(seeds, str) or not isinstance(seeds, Sequence | np.ndarray):
        raise InvalidArgumentError(
            f"seeds must be a number of runs or a sequence of integer seeds; got {seeds!r}"
        )
    out = [check_seed(s, f"seeds[{i}]") for i, s in enumerate(seeds)]
    if not out:
        raise InvalidArgumentError("seeds must not be empty")
    if any(s is None for s in out):
        raise InvalidArgumentError("seeds must be integers (None has no fixed stream)")
    return [int(s) for s in out if s is not None]


@contextlib.contextmanager
def _threads(workers: int | None) -> Iterator[None]:
    """Numba's thread count limited to ``workers`` (if given) for the ``with`` block.

    Runs are handed to the threads one at a time as they finish (a parallel chunk size
    of 1) rather than split in equal shares up front: runs of different lengths then
    keep every thread busy to the end.
    """
    import numba

    with numba.parallel_chunksize(1):
        if workers is None:
            yield
            return
        n = check_count(workers, "workers")
        before = numba.get_num_threads()
        numba.set_num_threads(min(n, int(numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]
        try:
            yield
        finally:
            numba.set_num_threads(before)
