"""Temporal-difference learning (Sutton & Barto chapters 6, 7, 8 and 12).

TD methods update an estimate from the next reward and the current estimate of the
next state (they bootstrap), one step at a time, without waiting for the episode's end:

* prediction of v_pi: :func:`td0`, :func:`n_step_td`, :func:`td_lambda`;
* control: :func:`sarsa`, :func:`q_learning`, :func:`expected_sarsa`,
  :func:`double_q_learning`, :func:`n_step_sarsa`, :func:`sarsa_lambda`,
  :func:`dyna_q` (planning from a learned model).

Each learner takes a :class:`~policylab.FiniteMDP` (compiled numba kernels) or a
Gymnasium env with ``Discrete`` observations and actions (the same kernel source run
as plain Python, see :mod:`policylab.tabular.td_kernels`), and returns a
:class:`~policylab.tabular.LearnResult` whose error curve is held against the exact
v_pi (prediction) or q* (control) where the model is known. :func:`seed_study` runs
one learner for many seeds at once (the studies of Figures 6.2-6.5).

Every TD learner's options mean the same: ``alpha`` (default 0.1) is a number, a
:class:`~policylab.tabular.Schedule` of each entry's update count or a schedule string
(``"1/n"``, ``"inverse:1,0.6,0.01"``, ``"exp:0.5,0.9999,0.01"``); ``epsilon`` (control,
default 0.1) the exploration rate of the epsilon-greedy behaviour, a number or a
schedule of the episode number (``"linear:1,0.01,5000"``); ``init`` (default 0) the
initial value of every non-terminal entry of the table (V(s) = 0.5 in Example 6.2);
``policy`` (prediction) the policy evaluated, a :class:`~policylab.Policy` or an (S, A)
array. Prediction learns V only: its result's ``q`` is the one-step lookahead of V
through the model (zeros without one), its ``policy`` the policy evaluated, and its
error that of V against the exact v_pi. The shared options (``gamma``, ``seed``,
``checkpoints``, ``max_steps``, ``model``, ``progress``) are
:class:`~policylab.tabular.LearnOptions`.

Example::

    import policylab as pl
    res = pl.tabular.q_learning(pl.problems.cliff_walking(), episodes=500, alpha=0.5,
                                epsilon=0.1, seed=0)
    res.episode_returns[-10:], res.to_policy()
"""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Unpack

import numpy as np

from policylab.exceptions import InvalidArgumentError, InvalidPolicyError
from policylab.tabular import td_kernels as tdk
from policylab.tabular.common import (
    GymStepper,
    StateIndex,
    as_env,
    check_count,
    check_fraction,
    check_gamma,
    env_name,
    is_finite_mdp,
)
from policylab.tabular.driver import (
    LearnOptions,
    Many,
    Plan,
    SeedRuns,
    add_entries,
    check_shared,
    learn_entry,
    seed_study,
)
from policylab.tabular.kernels import KernelMDP, writable
from policylab.tabular.registry import Option, register_algorithm
from policylab.tabular.result import LearnResult
from policylab.tabular.schedules import Schedule, as_schedule
from policylab.tabular.truth import GroundTruth, greedy_probs

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = [
    "SeedRuns",
    "double_q_learning",
    "dyna_q",
    "expected_sarsa",
    "n_step_sarsa",
    "n_step_td",
    "q_learning",
    "sarsa",
    "sarsa_lambda",
    "seed_study",
    "td0",
    "td_lambda",
]

Seed = int | np.random.Generator | None
Trace = Literal["accumulating", "replacing"]

_DEFAULT_ALPHA_PREDICTION = 0.1
_DEFAULT_ALPHA_CONTROL = 0.1
_DEFAULT_EPSILON = 0.1


# =============================================================================== the problem
@dataclass
class _Problem:
    """A learner's problem, resolved: the model (if known) and the env (general path)."""

    mdp: FiniteMDP | None
    env: Any | None
    index: StateIndex | None
    n_states: int
    n_actions: int
    mask: NDArray[np.bool_]
    states: tuple[Hashable, ...]
    actions: tuple[Hashable, ...]
    terminal: NDArray[np.bool_]
    name: str


def _resolve(problem: Any, model: FiniteMDP | None) -> _Problem:
    """The FiniteMDP (compiled path) or the Gymnasium env (general path) of ``problem``."""
    if is_finite_mdp(problem):
        fm: FiniteMDP = problem
        return _Problem(
            fm,
            None,
            None,
            fm.n_states,
            fm.n_actions,
            writable(fm.action_mask, np.bool_),
            fm.states,
            fm.actions,
            np.asarray(fm.terminal, dtype=bool),
            fm.name,
        )
    from gymnasium import spaces

    env = as_env(problem)  # the shared check: a Gymnasium env with Discrete actions
    base = getattr(env, "unwrapped", env)
    mdp: FiniteMDP | None = model if model is not None else getattr(base, "mdp", None)
    if mdp is None and getattr(base, "P", None) is not None:
        from policylab.mdp.finite import FiniteMDP

        mdp = FiniteMDP.from_gymnasium(base, name=env_name(env))
    name = env_name(env)
    A = int(env.action_space.n)
    space = env.observation_space
    if mdp is not None and mdp.n_actions != A:
        raise InvalidArgumentError(
            f"the model {mdp.name!r} has {mdp.n_actions} actions; the env {name!r} has {A}"
        )
    if isinstance(space, spaces.Discrete) and int(space.start) == 0:
        index = StateIndex.discrete(int(space.n))
        if mdp is not None and mdp.n_states != len(index):
            raise InvalidArgumentError(
                f"the model {mdp.name!r} has {mdp.n_states} states; the env {name!r} has "
                f"{len(index)}"
            )
    elif mdp is not None:  # observations are the model's state labels (Blackjack-v1's tuples)
        index = StateIndex.of_labels(mdp.states)
    else:
        raise InvalidArgumentError(
            "TD learners need Discrete(n) observations numbered from 0, or the env's model "
            f"(model=) to index its observations; got {env.observation_space}"
        )
    S = len(index)
    if mdp is not None:
        return _Problem(
            mdp,
            env,
            index,
            S,
            A,
            writable(mdp.action_mask, np.bool_),
            mdp.states,
            mdp.actions,
            np.asarray(mdp.terminal, dtype=bool),
            name,
        )
    return _Problem(
        None,
        env,
        index,
        S,
        A,
        np.ones((S, A), dtype=np.bool_),
        tuple(range(S)),
        tuple(range(A)),
        np.zeros(S, dtype=bool),
        name,
    )


def _policy_table(
    P: _Problem, policy: Policy | Any | None
) -> tuple[NDArray[np.float64], Policy | None]:
    """Pi as an (S, A) table for a prediction kernel, and the Policy for the exact v_pi."""
    from policylab.mdp.policy import Policy

    if policy is None:
        if P.mdp is not None:
            pol = Policy.uniform(P.mdp)
            return writable(pol.probs, np.float64), pol
        return np.full((P.n_states, P.n_actions), 1.0 / P.n_actions), None
    if isinstance(policy, Policy):
        if P.mdp is not None and (policy.states != P.mdp.states or policy.actions != P.mdp.actions):
            raise InvalidPolicyError(
                f"the policy's states/actions do not match the problem {P.name!r}"
            )
        return writable(policy.probs, np.float64), policy
    try:
        table = np.asarray(policy, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidPolicyError(
            "policy must be a Policy or an (S, A) array of probabilities; got "
            f"{type(policy).__name__}"
        ) from None
    if P.mdp is not None:
        pol = Policy.from_array(P.mdp, table)
        return writable(pol.probs, np.float64), pol
    if (
        table.shape != (P.n_states, P.n_actions)
        or np.any(table < 0)
        or not np.allclose(table.sum(axis=1), 1.0)
    ):
        raise InvalidPolicyError(
            f"policy must be an ({P.n_states}, {P.n_actions}) array whose rows sum to 1; "
            f"got shape {table.shape}"
        )
    return writable(table, np.float64), None


# =============================================================================== one run
_FAMILIES = {
    "td0": tdk.TD0,
    "one_step": tdk.ONE_STEP,
    "n_step": tdk.N_STEP,
    "lambda": tdk.LAMBDA,
    "dyna": tdk.DYNA,
}


@dataclass(frozen=True)
class _Algo:
    """Which kernel a learner runs, with its fixed settings."""

    name: str
    family: Literal["td0", "one_step", "n_step", "lambda", "dyna"]
    control: bool
    rule: int = tdk.SARSA
    n: int = 1
    lam: float = 0.0
    trace: int = tdk.TRACE_ACCUMULATING
    planning: int = 0

    def settings(
        self, gamma: float, alpha: Schedule, epsilon: Schedule, max_steps: int
    ) -> tdk.Settings:
        """The kernel's :class:`~policylab.tabular.td_kernels.Settings` of one run."""
        return tdk.Settings(
            float(gamma),
            alpha.params,
            epsilon.params,
            int(max_steps),
            self.rule,
            self.n,
            float(self.lam),
            self.trace,
            self.planning,
            self.control,
        )


def _tables(
    algo: _Algo, P: _Problem, pi: NDArray[np.float64], init: float, n_runs: int | None = None
) -> tdk.Tables:
    """Fresh tables of one run (``n_runs`` None) or of ``n_runs`` runs (leading run axis).

    The table learned starts at ``init`` (0 on terminal states); for anything but Double
    Q-learning ``q2`` and ``qb`` are the learned table itself.
    """
    S, A = P.n_states, P.n_actions
    lead = () if n_runs is None else (n_runs,)
    cols = A if algo.control else 1
    w = np.full((*lead, S, cols), float(init))
    w[..., P.terminal, :] = 0.0
    q2 = qb = w
    if algo.rule == tdk.DOUBLE_Q:
        q2 = w.copy()
        qb = w + q2  # the behaviour's Q1 + Q2, kept up to date by the kernel
    dyna = algo.family == "dyna"
    ring = algo.n + 1 if algo.family == "n_step" else 0
    return tdk.Tables(
        w,
        q2,
        qb,
        np.zeros((*lead, S, cols), dtype=np.int64),
        pi,
        np.full((*lead, S, A) if dyna else (*lead, 0, 0), -1, dtype=np.int64),
        np.zeros((*lead, S, A) if dyna else (*lead, 0, 0)),
        np.zeros((*lead, S * A + 1 if dyna else 1), dtype=np.int64),
        np.zeros((*lead, S, cols) if algo.family == "lambda" else (*lead, 0, 0)),
        np.zeros((*lead, ring), dtype=np.int64),
        np.zeros((*lead, ring), dtype=np.int64),
        np.zeros((*lead, ring)),
    )


def _episodes(episodes: int, n_runs: int | None = None) -> tdk.Episodes:
    """Empty per-episode records of one run (or of ``n_runs`` runs)."""
    lead = () if n_runs is None else (n_runs,)
    return tdk.Episodes(
        np.zeros((*lead, episodes)),
        np.zeros((*lead, episodes), dtype=np.int64),
        np.full((*lead, episodes), -1, dtype=np.int64),
    )


@dataclass
class _Run:
    """The tables of one run and the call of its kernel on either path."""

    algo: _Algo
    P: _Problem
    gamma: float
    max_steps: int
    rng: NDArray[np.uint64]
    env: Any
    model: tdk.Model
    settings: tdk.Settings
    tables: tdk.Tables
    out: tdk.Episodes
    alpha: str = ""  # the step size as written, for the divergence warning

    @classmethod
    def start(
        cls,
        algo: _Algo,
        P: _Problem,
        pi: NDArray[np.float64],
        *,
        gamma: float,
        alpha: Schedule,
        epsilon: Schedule,
        max_steps: int,
        rng: NDArray[np.uint64],
        env_seed: int,
        episodes: int,
        init: float,
    ) -> _Run:
        if P.env is None:  # compiled path: the kernel samples the model's arrays
            assert P.mdp is not None  # the compiled path always has a model
            env: Any = None
            model = tdk.model_tuple(KernelMDP.of(P.mdp, gamma), P.mask)
        else:  # general path: the kernel steps the Gymnasium env
            assert P.index is not None  # the general path always has an index
            env = GymStepper(P.env, P.index, env_seed)
            model = tdk.model_tuple(None, P.mask)
        return cls(
            algo,
            P,
            gamma,
            max_steps,
            rng,
            env,
            model,
            algo.settings(gamma, alpha, epsilon, max_steps),
            _tables(algo, P, pi, init),
            _episodes(episodes),
            str(alpha),
        )

    def __call__(self, k0: int, k1: int) -> int:
        """Run episodes k0 .. k1 - 1; return the environment steps taken."""
        family = _FAMILIES[self.algo.family]
        args = (self.env, self.model, self.tables, self.settings, self.out, self.rng, k0, k1)
        if self.env is None:
            return int(tdk.run_kernel(family, *args))
        return int(tdk.run_kernel.py_func(family, *args))  # the same source, as Python

    def estimate(self) -> tuple[Any, Any, None]:
        """What the error is measured on: Q (control) and V."""
        q, v = self.values()
        return (q if self.algo.control else None), v, None

    def outcome(self) -> dict[str, Any]:
        """The run's :class:`LearnResult` fields (with a warning if it diverged)."""
        P, algo, out = self.P, self.algo, self.out
        _warn_if_diverged(algo, P, self.gamma, self.max_steps, self.alpha, self.w, self.q2)
        counts = self.tables.counts
        counts = counts if algo.control else np.repeat(counts, P.n_actions, axis=1) * P.mask
        q, v = self.values()
        return {
            "states": P.states,
            "actions": P.actions,
            "q": q,
            "v": v,
            "policy": greedy_probs(q, P.mask) if algo.control else self.tables.pi.copy(),
            "terminal": P.terminal,
            "action_mask": P.mask,
            "counts": counts.astype(np.float64),
            "episode_returns": out.returns,
            "truncated": int(np.sum(out.lengths >= self.max_steps)),
            "episode_lengths": out.lengths,
            "first_actions": out.first_actions if algo.family == "one_step" else None,
        }

    @property
    def w(self) -> NDArray[np.float64]:
        """The table learned (V as (S, 1), or Q; Q1 for Double Q)."""
        return self.tables.w  # type: ignore[no-any-return]

    @property
    def q2(self) -> NDArray[np.float64]:
        """Q2 of Double Q-learning (else the learned table itself)."""
        return self.tables.q2  # type: ignore[no-any-return]

    def values(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(Q, V) of the run's tables (see :func:`_values`)."""
        return _values(self.algo, self.P, self.gamma, self.w, self.q2)


def _values(
    algo: _Algo, P: _Problem, gamma: float, w: NDArray[np.float64], q2: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Q (S, A) and V (S,) of learned tables, or of R runs' tables at once (leading axis).

    Control: Q the table (Q1 + Q2 averaged for Double Q) on A(s), V = max over A(s) of
    Q. Prediction learns V only; its Q is the one-step lookahead q(s, a) = sum p(s', r |
    s, a) [r + gamma V(s')] where the model is known, else zeros. V is 0 on terminals.
    """
    if algo.control:
        q = np.where(P.mask, (w + q2) / 2.0 if algo.rule == tdk.DOUBLE_Q else w, 0.0)
        v = np.where(P.mask.any(axis=1), np.where(P.mask, q, -np.inf).max(axis=-1), 0.0)
        v[..., P.terminal] = 0.0
        return q, v
    v = w[..., 0].copy()
    v[..., P.terminal] = 0.0
    if v.ndim == 2:
        return np.stack([_lookahead(P, gamma, row) for row in v]), v
    return _lookahead(P, gamma, v), v


def _lookahead(P: _Problem, gamma: float, v: NDArray[np.float64]) -> NDArray[np.float64]:
    """q(s, a) = sum p(s', r | s, a) [r + gamma V(s')] on A(s) (zeros without a model)."""
    if P.mdp is None or not np.all(np.isfinite(v)):
        return np.zeros((P.n_states, P.n_actions))
    from policylab.planning import action_values

    q = np.asarray(action_values(P.mdp.with_gamma(gamma), v))
    return np.where(P.mask, q, 0.0)


def _prepare(
    algo: _Algo, args: dict[str, Any]
) -> tuple[_Problem, NDArray[np.float64], Policy | None, float, Schedule, Schedule]:
    """The checked problem, policy table, truth policy, gamma and schedules of a call."""
    P = _resolve(args["problem"], args["model"])
    g = check_gamma(args["gamma"], P.mdp.gamma if P.mdp is not None else 1.0)
    default_alpha = _DEFAULT_ALPHA_CONTROL if algo.control else _DEFAULT_ALPHA_PREDICTION
    a = as_schedule(args["alpha"], Schedule.constant(default_alpha), "alpha")
    a.check_range(0.0, 1.0, "alpha")
    e = as_schedule(args.get("epsilon"), Schedule.constant(_DEFAULT_EPSILON), "epsilon")
    e.check_range(0.0, 1.0, "epsilon")
    policy = args.get("policy")
    if algo.control:
        if policy is not None:
            raise InvalidArgumentError(f"{algo.name} is a control method; it takes no policy")
        pi, truth_policy = np.zeros((P.n_states, P.n_actions)), None
    else:
        pi, truth_policy = _policy_table(P, policy)
    return P, pi, truth_policy, g, a, e


def _plan(algo: _Algo, args: dict[str, Any], params: dict[str, Any]) -> Plan:
    """The :class:`~policylab.tabular.driver.Plan` of a TD learner call."""
    episodes, max_steps, checkpoints = check_shared(args)
    P, pi, truth_policy, g, a, e = _prepare(algo, args)
    init = float(args["init"])
    mdp = P.mdp

    def truth() -> GroundTruth | None:
        if mdp is None:
            return None
        if algo.control:
            return GroundTruth.control(mdp, on="q", gamma=g)
        if truth_policy is None:
            return None
        return GroundTruth.prediction(mdp, truth_policy, on="v", gamma=g)

    def start(rng: NDArray[np.uint64], gen: np.random.Generator) -> _Run:
        return _Run.start(
            algo, P, pi, gamma=g, alpha=a, epsilon=e, max_steps=max_steps, rng=rng,
            env_seed=int(gen.integers(2**31 - 1)), episodes=episodes, init=init,
        )  # fmt: skip

    def many(rngs: NDArray[np.uint64]) -> Many:
        assert mdp is not None  # batched on a FiniteMDP only
        R = rngs.shape[0]
        tables = _tables(algo, P, pi, init, n_runs=R)
        out = _episodes(episodes, R)
        model = tdk.model_tuple(KernelMDP.of(mdp, g), P.mask)
        settings = algo.settings(g, a, e, max_steps)
        family = _FAMILIES[algo.family]
        steps = tdk.many_runs(family, model, tables, settings, out, rngs, episodes)
        _warn_if_diverged(algo, P, g, max_steps, str(a), tables.w, tables.q2)
        q, v = _values(algo, P, g, tables.w, tables.q2)
        first = out.first_actions if algo.family == "one_step" else None
        return Many(out.returns, out.lengths, q, v, first, int(steps.sum()))

    return Plan(
        algorithm=algo.name,
        problem=P.name,
        mdp=mdp,
        episodes=episodes,
        checkpoints=checkpoints,
        gamma=g,
        params={**params, "alpha": str(a), **({"epsilon": str(e)} if algo.control else {})},
        truth=truth,
        start=start,
        many=many if P.env is None else None,
        compiled=P.env is None,
    )


def _warn_if_diverged(
    algo: _Algo,
    P: _Problem,
    gamma: float,
    max_steps: int,
    alpha: str,
    w: NDArray[np.float64],
    q2: NDArray[np.float64],
) -> None:
    """Warn when the tables (of one run or of many) diverged.

    Diverged: non-finite values, or (with a model) values beyond ten times the largest
    possible return, max|r| / (1 - gamma) (max|r| * max_steps for gamma = 1).
    """
    diverged = not (np.all(np.isfinite(w)) and np.all(np.isfinite(q2)))
    if not diverged and P.mdp is not None and P.mdp.n_outcomes:
        r_max = float(np.abs(P.mdp.rewards).max())
        horizon = 1.0 / (1.0 - gamma) if gamma < 1.0 else float(max_steps)
        largest = max(float(np.abs(w).max()), float(np.abs(q2).max()))
        diverged = largest > 10.0 * max(r_max, 1e-12) * horizon
    if not diverged:
        return
    import warnings

    hint = (
        " (accumulating traces diverge when alpha is large for the trace length, S&B "
        "Figure 12.6; try replacing traces)"
        if algo.family == "lambda"
        else ""
    )
    warnings.warn(
        f"{algo.name}: the estimates diverged (beyond any possible return) with alpha "
        f"{alpha}; use a smaller step size{hint}",
        RuntimeWarning,
        stacklevel=6,
    )


# =============================================================================== learners
# =============================================================================== the entries
_SCHEDULE = "Schedule | float | str | None"

_ALPHA = Option(
    "--alpha",
    "alpha",
    "schedule",
    "Step size alpha: a number, or a schedule of each entry's update count "
    "(1/n, inverse:1,0.6,0.01, exp:0.5,0.999,0.01, linear:0.5,0.01,10000).",
    annotation=_SCHEDULE,
    value="0.1",
    doc="Step size: a number, a :class:`Schedule` or a schedule string.",
)
_EPSILON = Option(
    "--epsilon",
    "epsilon",
    "schedule",
    "Exploration rate of the epsilon-greedy behaviour: a number, or a schedule of the "
    "episode number (1/n, exp:1,0.999,0.01, linear:1,0.01,5000).",
    annotation=_SCHEDULE,
    value="0.1",
    doc="Exploration rate: a number, a :class:`Schedule` or a schedule string.",
)
_INIT = Option(
    "--init",
    "init",
    "float",
    "Initial value of every non-terminal entry of the table (high values explore optimistically).",
    annotation="float",
    value="0.0",
    doc="Initial value of the table's non-terminal entries (optimistic if high).",
)
_N = Option(
    "--n",
    "n",
    "int",
    "Number of steps n of the n-step return (n = 1 is one-step TD).",
    annotation="int",
    value="4",
)
_LAM = Option(
    "--lambda",
    "lam",
    "float",
    "Trace-decay rate lambda in [0, 1] (0 is one-step TD).",
    annotation="float",
    value="0.8",
)
_TRACE = Option(
    "--trace",
    "trace",
    "str",
    "Eligibility trace: accumulating or replacing.",
    annotation="Trace",
    value='"accumulating"',
)
_PLAN = Option(
    "--planning-steps",
    "planning_steps",
    "int",
    "Planning updates from the learned model after each real step (0 is Q-learning).",
    annotation="int",
    value="5",
)


@dataclass(frozen=True)
class TDEntry:
    """One TD learner: everything its public function, the registry and the CLI say.

    The public function (signature and docstring) is generated from it by
    ``python -m policylab.tabular._generate``; the ``learn`` subcommand and
    :func:`seed_study` read the registered spec built from it.

    Attributes:
        name: Registry and command-line name (``"n-step-sarsa"``).
        function: The public function's name (``"n_step_sarsa"``).
        family: The episode loop (see :mod:`policylab.tabular.td_kernels`).
        control: Learns Q (control) rather than V of a given policy (prediction).
        title: The docstring's first line, with the book section.
        equation: The update, as the docstring states it.
        description: One line for ``policylab learn --help``.
        own: The learner's own options, before the shared ones.
        rule: The one-step rule (``one_step`` family).
        default_episodes: Episodes when not given.
    """

    name: str
    function: str
    family: Literal["td0", "one_step", "n_step", "lambda", "dyna"]
    control: bool
    title: str
    equation: str
    description: str
    own: tuple[Option, ...] = ()
    rule: int = tdk.SARSA
    default_episodes: int = 500

    @property
    def options(self) -> tuple[Option, ...]:
        """The command-line options: its own, then alpha, epsilon (control) and init."""
        return (*self.own, _ALPHA, *((_EPSILON,) if self.control else ()), _INIT)

    def plan(self, args: dict[str, Any]) -> Plan:
        """The driver's :class:`~policylab.tabular.driver.Plan` of a call of this learner."""
        algo, params = _make_algo(self, {o.param: args[o.param] for o in self.own})
        return _plan(algo, args, params)


TD_ENTRIES: tuple[TDEntry, ...] = (
    TDEntry(
        "td0",
        "td0",
        "td0",
        False,
        "Tabular TD(0) prediction of v_pi (S&B section 6.1).",
        "V(S_t) <- V(S_t) + alpha [R_{t+1} + gamma V(S_{t+1}) - V(S_t)] after every step.",
        "TD(0) prediction of v_pi (S&B 6.1).",
        default_episodes=100,
    ),
    TDEntry(
        "n-step-td",
        "n_step_td",
        "n_step",
        False,
        "n-step TD prediction of v_pi (S&B section 7.1).",
        "V(S_tau) <- V(S_tau) + alpha [G_{tau:tau+n} - V(S_tau)] with the n-step return\n"
        "G_{tau:tau+n} = R_{tau+1} + gamma R_{tau+2} + ... + gamma^{n-1} R_{tau+n} +\n"
        "gamma^n V(S_{tau+n}) (no bootstrap past the episode's end). n = 1 is TD(0).",
        "n-step TD prediction of v_pi (S&B 7.1).",
        (_N,),
        default_episodes=100,
    ),
    TDEntry(
        "td-lambda",
        "td_lambda",
        "lambda",
        False,
        "Tabular TD(lambda) prediction with eligibility traces (S&B section 12.2).",
        "delta_t = R_{t+1} + gamma V(S_{t+1}) - V(S_t); e(S_t) <- e(S_t) + 1\n"
        "(accumulating) or 1 (replacing); V <- V + alpha delta_t e; e <- gamma lambda e.\n"
        "lambda = 0 is TD(0); lambda = 1 (accumulating, offline) approaches Monte Carlo.",
        "TD(lambda) prediction with eligibility traces (S&B 12.2).",
        (_LAM, _TRACE),
        default_episodes=100,
    ),
    TDEntry(
        "sarsa",
        "sarsa",
        "one_step",
        True,
        "Sarsa, on-policy TD control (S&B section 6.4).",
        "Q(S, A) <- Q(S, A) + alpha [R + gamma Q(S', A') - Q(S, A)], with A' the\n"
        "epsilon-greedy action actually taken next.",
        "Sarsa: on-policy TD control (S&B 6.4).",
    ),
    TDEntry(
        "q-learning",
        "q_learning",
        "one_step",
        True,
        "Q-learning, off-policy TD control (S&B section 6.5).",
        "Q(S, A) <- Q(S, A) + alpha [R + gamma max_a Q(S', a) - Q(S, A)].",
        "Q-learning: off-policy TD control (S&B 6.5).",
        rule=tdk.Q_LEARNING,
    ),
    TDEntry(
        "expected-sarsa",
        "expected_sarsa",
        "one_step",
        True,
        "Expected Sarsa (S&B section 6.6).",
        "Q(S, A) <- Q(S, A) + alpha [R + gamma sum_a pi(a | S') Q(S', a) - Q(S, A)], pi the\n"
        "epsilon-greedy policy of Q.",
        "Expected Sarsa (S&B 6.6).",
        rule=tdk.EXPECTED_SARSA,
    ),
    TDEntry(
        "double-q-learning",
        "double_q_learning",
        "one_step",
        True,
        "Double Q-learning (S&B section 6.7), which removes the maximisation bias.",
        "With probability 1/2: Q1(S, A) <- Q1 + alpha [R + gamma Q2(S', argmax_a Q1(S', a))\n"
        "- Q1(S, A)], else the same with Q1 and Q2 swapped; behaviour epsilon-greedy in\n"
        "Q1 + Q2. ``result.q`` is (Q1 + Q2) / 2.",
        "Double Q-learning, no maximisation bias (S&B 6.7).",
        rule=tdk.DOUBLE_Q,
    ),
    TDEntry(
        "n-step-sarsa",
        "n_step_sarsa",
        "n_step",
        True,
        "n-step Sarsa (S&B section 7.2).",
        "Q(S_tau, A_tau) <- Q + alpha [G_{tau:tau+n} - Q(S_tau, A_tau)] with G = R_{tau+1} +\n"
        "... + gamma^{n-1} R_{tau+n} + gamma^n Q(S_{tau+n}, A_{tau+n}). n = 1 is Sarsa.",
        "n-step Sarsa (S&B 7.2).",
        (_N,),
    ),
    TDEntry(
        "sarsa-lambda",
        "sarsa_lambda",
        "lambda",
        True,
        "Tabular Sarsa(lambda) with eligibility traces (S&B section 12.7).",
        "delta = R + gamma Q(S', A') - Q(S, A); e(S, A) <- e + 1 (accumulating) or 1\n"
        "(replacing); Q <- Q + alpha delta e; e <- gamma lambda e. lambda = 0 is Sarsa.",
        "Sarsa(lambda) with eligibility traces (S&B 12.7).",
        (_LAM, _TRACE),
    ),
    TDEntry(
        "dyna-q",
        "dyna_q",
        "dyna",
        True,
        "Tabular Dyna-Q (S&B section 8.2): Q-learning plus planning from a learned model.",
        "After each real step, Model(S, A) <- (R, S') and ``planning_steps`` Q-learning\n"
        "updates on pairs drawn uniformly from those seen, with (R, S') from the model (the\n"
        "last outcome seen: exact on deterministic problems). ``planning_steps = 0`` is\n"
        "Q-learning.",
        "Dyna-Q: Q-learning plus planning from a learned model (S&B 8.2).",
        (_PLAN,),
    ),
)


def _make_algo(entry: TDEntry, own: dict[str, Any]) -> tuple[_Algo, dict[str, Any]]:
    """The kernel settings of a TD learner from its own options, checked, and their record."""
    fields: dict[str, Any] = {}
    params: dict[str, Any] = {}
    if "n" in own:
        fields["n"] = _check_n(own["n"])
        params["n"] = fields["n"]
    if "lam" in own:
        fields["lam"] = _check_lambda(own["lam"])
        params["lambda"] = fields["lam"]
    if "trace" in own:
        fields["trace"] = _check_trace(own["trace"])
        params["trace"] = own["trace"]
    if "planning_steps" in own:
        fields["planning"] = _check_planning(own["planning_steps"])
        params["planning_steps"] = fields["planning"]
    algo = _Algo(entry.name, entry.family, entry.control, rule=entry.rule, **fields)
    return algo, params


def _check_n(n: Any) -> int:
    return check_count(n, "n (the number of steps)")


def _check_lambda(lam: Any) -> float:
    return check_fraction(lam, "lambda")


def _check_trace(trace: Any) -> int:
    kinds = {"accumulating": tdk.TRACE_ACCUMULATING, "replacing": tdk.TRACE_REPLACING}
    if trace not in kinds:
        raise InvalidArgumentError(f"trace must be 'accumulating' or 'replacing'; got {trace!r}")
    return kinds[trace]


def _check_planning(k: Any) -> int:
    return check_count(k, "planning_steps", minimum=0)


# ======================================================================= the public learners
# generated by `python -m policylab.tabular._generate` from TD_ENTRIES: edit the entries
# (or the generator) and run it again; tests/tabular/test_registry.py checks it is current.
# <generated learners>


def td0(
    problem: FiniteMDP | Any,
    policy: Policy | Any = None,
    *,
    episodes: int = 100,
    alpha: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Tabular TD(0) prediction of v_pi (S&B section 6.1).

    V(S_t) <- V(S_t) + alpha [R_{t+1} + gamma V(S_{t+1}) - V(S_t)] after every step.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        policy: A :class:`~policylab.Policy` or an (S, A) array (default: equiprobable).
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error of V is against v_pi, as above).
    """
    return learn_entry("td0", locals())


def n_step_td(
    problem: FiniteMDP | Any,
    policy: Policy | Any = None,
    *,
    n: int = 4,
    episodes: int = 100,
    alpha: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """n-step TD prediction of v_pi (S&B section 7.1).

    V(S_tau) <- V(S_tau) + alpha [G_{tau:tau+n} - V(S_tau)] with the n-step return
    G_{tau:tau+n} = R_{tau+1} + gamma R_{tau+2} + ... + gamma^{n-1} R_{tau+n} +
    gamma^n V(S_{tau+n}) (no bootstrap past the episode's end). n = 1 is TD(0).

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        policy: A :class:`~policylab.Policy` or an (S, A) array (default: equiprobable).
        n: Number of steps n of the n-step return (n = 1 is one-step TD).
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error of V is against v_pi, as above).
    """
    return learn_entry("n-step-td", locals())


def td_lambda(
    problem: FiniteMDP | Any,
    policy: Policy | Any = None,
    *,
    lam: float = 0.8,
    trace: Trace = "accumulating",
    episodes: int = 100,
    alpha: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Tabular TD(lambda) prediction with eligibility traces (S&B section 12.2).

    delta_t = R_{t+1} + gamma V(S_{t+1}) - V(S_t); e(S_t) <- e(S_t) + 1
    (accumulating) or 1 (replacing); V <- V + alpha delta_t e; e <- gamma lambda e.
    lambda = 0 is TD(0); lambda = 1 (accumulating, offline) approaches Monte Carlo.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        policy: A :class:`~policylab.Policy` or an (S, A) array (default: equiprobable).
        lam: Trace-decay rate lambda in [0, 1] (0 is one-step TD).
        trace: Eligibility trace: accumulating or replacing.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error of V is against v_pi, as above).
    """
    return learn_entry("td-lambda", locals())


def sarsa(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Sarsa, on-policy TD control (S&B section 6.4).

    Q(S, A) <- Q(S, A) + alpha [R + gamma Q(S', A') - Q(S, A)], with A' the
    epsilon-greedy action actually taken next.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("sarsa", locals())


def q_learning(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Q-learning, off-policy TD control (S&B section 6.5).

    Q(S, A) <- Q(S, A) + alpha [R + gamma max_a Q(S', a) - Q(S, A)].

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("q-learning", locals())


def expected_sarsa(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Expected Sarsa (S&B section 6.6).

    Q(S, A) <- Q(S, A) + alpha [R + gamma sum_a pi(a | S') Q(S', a) - Q(S, A)], pi the
    epsilon-greedy policy of Q.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("expected-sarsa", locals())


def double_q_learning(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Double Q-learning (S&B section 6.7), which removes the maximisation bias.

    With probability 1/2: Q1(S, A) <- Q1 + alpha [R + gamma Q2(S', argmax_a Q1(S', a))
    - Q1(S, A)], else the same with Q1 and Q2 swapped; behaviour epsilon-greedy in
    Q1 + Q2. ``result.q`` is (Q1 + Q2) / 2.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("double-q-learning", locals())


def n_step_sarsa(
    problem: FiniteMDP | Any,
    *,
    n: int = 4,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """n-step Sarsa (S&B section 7.2).

    Q(S_tau, A_tau) <- Q + alpha [G_{tau:tau+n} - Q(S_tau, A_tau)] with G = R_{tau+1} +
    ... + gamma^{n-1} R_{tau+n} + gamma^n Q(S_{tau+n}, A_{tau+n}). n = 1 is Sarsa.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        n: Number of steps n of the n-step return (n = 1 is one-step TD).
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("n-step-sarsa", locals())


def sarsa_lambda(
    problem: FiniteMDP | Any,
    *,
    lam: float = 0.8,
    trace: Trace = "accumulating",
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Tabular Sarsa(lambda) with eligibility traces (S&B section 12.7).

    delta = R + gamma Q(S', A') - Q(S, A); e(S, A) <- e + 1 (accumulating) or 1
    (replacing); Q <- Q + alpha delta e; e <- gamma lambda e. lambda = 0 is Sarsa.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        lam: Trace-decay rate lambda in [0, 1] (0 is one-step TD).
        trace: Eligibility trace: accumulating or replacing.
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("sarsa-lambda", locals())


def dyna_q(
    problem: FiniteMDP | Any,
    *,
    planning_steps: int = 5,
    episodes: int = 500,
    alpha: Schedule | float | str | None = 0.1,
    epsilon: Schedule | float | str | None = 0.1,
    init: float = 0.0,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Tabular Dyna-Q (S&B section 8.2): Q-learning plus planning from a learned model.

    After each real step, Model(S, A) <- (R, S') and ``planning_steps`` Q-learning
    updates on pairs drawn uniformly from those seen, with (R, S') from the model (the
    last outcome seen: exact on deterministic problems). ``planning_steps = 0`` is
    Q-learning.

    Args:
        problem: A FiniteMDP (compiled) or a Gymnasium env with Discrete observations.
        planning_steps: Planning updates from the learned model after each real step (0 is
            Q-learning).
        episodes: Number of episodes.
        alpha: Step size: a number, a :class:`Schedule` or a schedule string.
        epsilon: Exploration rate: a number, a :class:`Schedule` or a schedule string.
        init: Initial value of the table's non-terminal entries (optimistic if high).
        **options: The options every learner shares, :class:`~policylab.tabular.LearnOptions`.

    Returns:
        A :class:`LearnResult` (the error is against q* where the model is known).
    """
    return learn_entry("dyna-q", locals())


# </generated learners>

add_entries(TD_ENTRIES)
for _entry in TD_ENTRIES:
    register_algorithm(
        _entry.name,
        globals()[_entry.function],
        _entry.description,
        options=_entry.options,
        kind="control" if _entry.control else "prediction",
        default_episodes=_entry.default_episodes,
    )
