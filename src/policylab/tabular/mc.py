"""Monte Carlo methods (notes section 6; Sutton & Barto chapter 5).

Generate episodes with a policy, then average the returns that follow the visits of
each state (V) and each state-action pair (Q): the notes' Q-table. With first-visit
MC only the first visit of a pair in an episode counts; with every-visit MC every
visit does. The averages are kept incrementally with visit counts,

    N(s, a) <- N(s, a) + 1,   Q(s, a) <- Q(s, a) + alpha_N (G_t - Q(s, a)),

where alpha_N = 1/N gives the exact sample average (constant alpha gives
constant-alpha MC). The notes' last step, a greedy policy from the Q-table, is
``result.policy``.

Learners:

* :func:`mc_prediction`: estimate v_pi and q_pi of a given policy (first- or
  every-visit).
* :func:`mc_control`: on-policy control, with exploring starts (the greedy policy,
  S_0 and A_0 uniform) or epsilon-greedy with a GLIE schedule (epsilon = 1/sqrt(n(s)) by
  default); sample-average or constant-alpha updates.
* :func:`mc_off_policy`: off-policy prediction of a target policy from a behaviour
  policy's episodes, or control of the greedy policy, by ordinary or weighted
  importance sampling.

Each runs on a :class:`~policylab.FiniteMDP` (compiled kernels) or on a Gymnasium env
(a Python loop); both call the same compiled update :func:`mc_episode_update`.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, Unpack

import numba as nb
import numpy as np
from numba import prange

from policylab.exceptions import InvalidArgumentError, InvalidPolicyError
from policylab.tabular.common import (
    StateIndex,
    as_env,
    check_gamma,
    env_name,
    grow_rows,
    is_finite_mdp,
    start_state,
)
from policylab.tabular.driver import (
    LearnOptions,
    Many,
    Plan,
    Run,
    add_entries,
    check_shared,
    learn_entry,
)
from policylab.tabular.kernels import (
    EPSILON_GREEDY,
    FIXED_POLICY,
    Behaviour,
    EpisodeBuffers,
    KernelMDP,
    Model,
    behaviour_epsilon,
    choose_action,
    episode_loop,
    exploring_start_state,
    generate_episode,
    writable,
)
from policylab.tabular.registry import Option, register_algorithm
from policylab.tabular.result import LearnResult
from policylab.tabular.rules.mc import (
    AVERAGE,
    IS_CONTROL,
    IS_PREDICTION,
    MCScratch,
    MCSettings,
    MCTables,
    episode_return,
    first_visit_flags,
    mc_episode_update,
)
from policylab.tabular.schedules import CONSTANT, Schedule, as_schedule, schedule_value
from policylab.tabular.truth import GroundTruth, greedy_probs

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = [
    "AVERAGE",
    "IS_CONTROL",
    "IS_PREDICTION",
    "episode_return",
    "first_visit_flags",
    "mc_control",
    "mc_episode_update",
    "mc_off_policy",
    "mc_prediction",
]

Seed = int | np.random.Generator | None


# =============================================================================== fast path
class _MCRun(NamedTuple):
    """Everything one Monte Carlo run updates: tables, the (S, A) Q, buffers, records."""

    tables: MCTables
    q: Any
    buf: EpisodeBuffers
    scratch: MCScratch
    returns: Any
    lengths: Any


@episode_loop
def _mc_chunk(
    model: Model,
    behaviour: Behaviour,
    settings: MCSettings,
    run: _MCRun,
    rng: NDArray[np.uint64],
    k0: int,
    k1: int,
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Run episodes k0..k1-1 on the outcome table; return (steps, truncated episodes).

    Each episode: generate it with the behaviour, record its return G_0, and (unless it
    was truncated: Monte Carlo needs complete episodes) update the tables from it.
    """
    tables, q, buf, scratch, returns = run.tables, run.q, run.buf, run.scratch, run.returns
    steps = 0
    truncated = 0
    for k in range(k0, k1):
        eps = schedule_value(behaviour.epsilon, k + 1.0)
        T, cut = generate_episode(model, behaviour, q, eps, tables.nv, rng, buf)
        steps += T
        run.lengths[k] = T
        returns[k] = episode_return(buf.r, T, settings.gamma)
        if cut:
            truncated += 1
            continue
        mc_episode_update(settings, tables, buf, scratch, model.mask, T, k + 1)
    return steps, truncated


class _Stack(NamedTuple):
    """The arrays of R runs (leading run axis), flat: what the parallel loop takes."""

    q2: Any
    q: Any
    nq: Any
    cq: Any
    v: Any
    nv: Any
    cv: Any
    s: Any
    a: Any
    r: Any
    b: Any
    keys: Any
    flags_q: Any
    flags_v: Any
    mark_q: Any
    mark_v: Any
    returns: Any
    lengths: Any


def _stack(runs: _MCRun) -> _Stack:
    return _Stack(runs.q, *runs.tables, *runs.buf, *runs.scratch, runs.returns, runs.lengths)


@nb.njit(cache=True, nogil=True)
def _run_of(x: _Stack, r: int | np.int64) -> _MCRun:  # pragma: no cover - compiled
    """Run r of stacked runs (views of its slices); ``r`` an int64 (one compiled copy)."""
    return _MCRun(
        MCTables(x.q[r], x.nq[r], x.cq[r], x.v[r], x.nv[r], x.cv[r]),
        x.q2[r],
        EpisodeBuffers(x.s[r], x.a[r], x.r[r], x.b[r]),
        MCScratch(x.keys[r], x.flags_q[r], x.flags_v[r], x.mark_q[r], x.mark_v[r]),
        x.returns[r],
        x.lengths[r],
    )


@nb.njit(cache=True, parallel=True)
def _many_mc_runs(
    model: Model,
    behaviour: Behaviour,
    settings: MCSettings,
    runs: _Stack,
    rngs: NDArray[np.uint64],
    episodes: int,
) -> NDArray[np.int64]:  # pragma: no cover - compiled
    """R independent runs in parallel (``prange``), returning (R, 2) steps and truncated.

    ``runs`` holds every array with a leading run axis. Run r touches only its slices
    and its RNG stream ``rngs[r]``, so its numbers are those of the run alone. The
    stream is advanced in a copy of its own (two runs' 32-byte states share a cache
    line, which two threads would otherwise both write at every draw).
    """
    n_runs = rngs.shape[0]
    out = np.zeros((n_runs, 2), dtype=np.int64)
    for r in prange(n_runs):
        rng = rngs[r].copy()
        # int64 arguments, as the single runs pass them (the prange index is unsigned and
        # 0 a literal): other types would compile a second copy of the episode loop
        run = _run_of(runs, np.int64(r))
        k0 = int(0)  # noqa: UP018, RUF046
        steps, truncated = _mc_chunk(model, behaviour, settings, run, rng, k0, episodes)
        rngs[r] = rng
        out[r, 0] = steps
        out[r, 1] = truncated
    return out


def _mc_run(S: int, A: int, max_steps: int, episodes: int, n_runs: int | None = None) -> _MCRun:
    """Fresh arrays of one run (``n_runs`` None) or of ``n_runs`` runs (leading axis)."""
    lead = () if n_runs is None else (n_runs,)
    q = np.zeros((*lead, S, A))
    m = max_steps
    return _MCRun(
        MCTables(
            q.reshape(*lead, S * A),
            np.zeros((*lead, S * A)),
            np.zeros((*lead, S * A)),
            np.zeros((*lead, S)),
            np.zeros((*lead, S)),
            np.zeros((*lead, S)),
        ),
        q,
        EpisodeBuffers(
            np.zeros((*lead, m + 1), dtype=np.int64),
            np.zeros((*lead, m), dtype=np.int64),
            np.zeros((*lead, m)),
            np.zeros((*lead, m)),
        ),
        MCScratch(
            np.zeros((*lead, m), dtype=np.int64),
            np.zeros((*lead, m), dtype=np.bool_),
            np.zeros((*lead, m), dtype=np.bool_),
            np.zeros((*lead, S * A), dtype=np.int64),
            np.zeros((*lead, S), dtype=np.int64),
        ),
        np.zeros((*lead, episodes)),
        np.zeros((*lead, episodes), dtype=np.int64),
    )


def _grow(run: _MCRun, S: int) -> _MCRun:
    """``run`` with room for S states (general path with a growing state index)."""
    if run.q.shape[0] >= S:
        return run
    A = run.q.shape[1]
    q = grow_rows(run.q, S)
    n = q.shape[0]
    t, c = run.tables, run.scratch
    return run._replace(
        tables=MCTables(
            q.reshape(n * A),
            _grow_flat(t.nq, n * A),
            _grow_flat(t.cq, n * A),
            _grow_flat(t.v, n),
            _grow_flat(t.nv, n),
            _grow_flat(t.cv, n),
        ),
        q=q,
        scratch=c._replace(mark_q=_grow_flat(c.mark_q, n * A), mark_v=_grow_flat(c.mark_v, n)),
    )


def _grow_flat(arr: NDArray[Any], n: int) -> NDArray[Any]:
    if arr.shape[0] >= n:
        return arr
    out = np.zeros(n, dtype=arr.dtype)
    out[: arr.shape[0]] = arr
    return out


# =============================================================================== the plan
class _Setup(NamedTuple):
    """What one Monte Carlo learner call sets (the rest is shared): its entry's data.

    ``kind``: the update (:data:`AVERAGE`, :data:`IS_PREDICTION`, :data:`IS_CONTROL`);
    ``policy``/``policy_kind``: the behaviour (a fixed policy, or epsilon-greedy in Q
    with ``epsilon``, by state visits with ``eps_by_state``, from ``exploring_starts``);
    ``first_visit``, ``alpha``, ``weighted`` and ``target`` of the update;
    ``truth_kind``, ``truth_policy`` and ``error_on``: what the error is measured
    against; ``params``: the result's record of the settings.
    """

    kind: int
    policy: Any
    policy_kind: int
    epsilon: Schedule
    eps_by_state: bool
    exploring_starts: bool
    first_visit: bool
    alpha: Schedule
    weighted: bool
    target: Policy | None
    truth_kind: Literal["prediction", "control"]
    truth_policy: Policy | None
    error_on: Literal["v", "q"]
    params: dict[str, Any]


@dataclass(frozen=True)
class MCEntry:
    """One Monte Carlo learner for the driver: its name and how its options set it up.

    Attributes:
        name: Registry and command-line name.
        setup: ``setup(args)``: the :class:`_Setup` of a call's arguments, checked.
    """

    name: str
    setup: Callable[[dict[str, Any]], _Setup]

    def plan(self, args: dict[str, Any]) -> Plan:
        """The driver's :class:`~policylab.tabular.driver.Plan` of a call of this learner."""
        return _plan(self.name, args, self.setup(args))


def _plan(name: str, args: dict[str, Any], st: _Setup) -> Plan:
    """The plan of a Monte Carlo call: the compiled path on a FiniteMDP, else the env loop."""
    episodes, max_steps, checkpoints = check_shared(args)
    problem, start = args["problem"], args["start"]
    mdp: FiniteMDP | None
    if is_finite_mdp(problem):
        mdp, env = problem, None
    else:
        env = as_env(problem)
        mdp = args["model"]
        if mdp is None:
            mdp = getattr(getattr(env, "unwrapped", env), "mdp", None)
        if start is not None:
            raise InvalidArgumentError(
                "start= is only supported on a FiniteMDP; reset the env instead"
            )
    g = check_gamma(args["gamma"], mdp.gamma if mdp is not None else 1.0)
    if mdp is not None and not mdp.terminal.any():
        raise InvalidArgumentError(
            f"Monte Carlo needs an episodic task; {mdp.name!r} has no terminal state (use a TD "
            "method for continuing tasks)"
        )
    keeps_v = _keeps_v(st.kind, st.truth_kind)

    def truth() -> GroundTruth | None:
        if mdp is None or not args["score"]:
            return None
        if st.truth_kind == "prediction":
            assert st.truth_policy is not None  # set by the setups, never from user input
            return GroundTruth.prediction(mdp, st.truth_policy, on=st.error_on, gamma=g)
        return GroundTruth.control(mdp, on=st.error_on, gamma=g)

    many: Callable[[NDArray[np.uint64]], Many] | None = None
    if env is None:
        assert mdp is not None
        fm: FiniteMDP = mdp
        model, behaviour, settings = _fast_setup(fm, st, start, g)
        S, A = fm.n_states, fm.n_actions

        def start_run(rng: NDArray[np.uint64], gen: np.random.Generator) -> Run:
            arrays = _mc_run(S, A, max_steps, episodes)
            return _CompiledRun(fm, model, behaviour, settings, arrays, rng, keeps_v)

        def many(rngs: NDArray[np.uint64]) -> Many:
            runs = _mc_run(S, A, max_steps, episodes, n_runs=rngs.shape[0])
            counts = _many_mc_runs(model, behaviour, settings, _stack(runs), rngs, episodes)
            mask, terminal = _mask_terminal(fm)
            q, v = _q_and_v(runs.q, runs.tables.v, mask, terminal, keeps_v)
            return Many(runs.returns, runs.lengths, q, v, None, int(counts[:, 0].sum()))

    else:

        def start_run(rng: NDArray[np.uint64], gen: np.random.Generator) -> Run:
            return _EnvRun(env, mdp, st, g, rng, gen, episodes, max_steps, name)

    return Plan(
        algorithm=name,
        problem=mdp.name if mdp is not None else env_name(env),
        mdp=mdp,
        episodes=episodes,
        checkpoints=checkpoints,
        gamma=g,
        params=st.params,
        truth=truth,
        start=start_run,
        many=many,
        compiled=env is None,
    )


def _keeps_v(kind: int, truth_kind: str) -> bool:
    """Whether V is learned itself (prediction) rather than read off Q as max_a Q."""
    return (kind == AVERAGE and truth_kind == "prediction") or kind == IS_PREDICTION


def _mask_terminal(mdp: FiniteMDP) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    return np.asarray(mdp.action_mask, dtype=bool), np.asarray(mdp.terminal, dtype=bool)


def _q_and_v(
    q: NDArray[np.float64],
    v_learned: NDArray[np.float64],
    mask: NDArray[np.bool_],
    terminal: NDArray[np.bool_],
    keeps_v: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The result's Q (0 off A(s)) and V (learned, or max over A(s) of Q; 0 if terminal).

    ``q`` (..., S, A) and ``v_learned`` (..., S) may carry a leading run axis.
    """
    q = np.where(mask, q, 0.0)
    if keeps_v:
        v = v_learned.copy()
    else:
        v = np.where(mask, q, -np.inf).max(axis=-1)
        v[..., ~mask.any(axis=1)] = 0.0
    v[..., terminal] = 0.0
    return q, v


def _outcome(
    run: _MCRun,
    labels: tuple[Hashable, ...],
    mdp: FiniteMDP | None,
    truncated: int,
    keeps_v: bool,
) -> dict[str, Any]:
    """The :class:`LearnResult` fields of a finished Monte Carlo run over ``labels``."""
    S, A = len(labels), run.q.shape[1]
    if mdp is not None:
        mask, terminal = _mask_terminal(mdp)
        actions = mdp.actions
    else:
        mask, terminal = np.ones((S, A), dtype=bool), np.zeros(S, dtype=bool)
        actions = tuple(range(A))
    q, v = _q_and_v(run.q[:S], run.tables.v[:S], mask, terminal, keeps_v)
    return {
        "states": tuple(labels),
        "actions": tuple(actions),
        "q": q,
        "v": v,
        "policy": greedy_probs(q, mask),
        "terminal": terminal,
        "action_mask": mask,
        "counts": run.tables.nq[: S * A].reshape(S, A).copy(),
        "episode_returns": run.returns,
        "truncated": int(truncated),
        "episode_lengths": run.lengths,
    }


def _fast_setup(
    mdp: FiniteMDP, st: _Setup, start: Hashable | None, gamma: float
) -> tuple[Model, Behaviour, MCSettings]:
    """The compiled path's model, behaviour and update settings."""
    km = KernelMDP.of(mdp, gamma)
    S, A = mdp.n_states, mdp.n_actions
    fixed = st.policy_kind == FIXED_POLICY
    pi = writable(st.policy.probs if fixed else np.zeros((S, A)), np.float64)
    target = st.target.probs.ravel() if st.target is not None else np.zeros(S * A)
    initial = writable(start_state(mdp, start), np.float64)
    model = Model(
        km.indptr, km.next_states, km.cdf, km.rewards, km.terminal, initial, km.mask
    )  # fmt: skip
    behaviour = Behaviour(
        st.policy_kind, pi, st.epsilon.params, st.eps_by_state, st.exploring_starts
    )
    settings = MCSettings(
        gamma, st.kind, st.first_visit, st.alpha.params, st.weighted, writable(target, np.float64)
    )
    return model, behaviour, settings


class _CompiledRun:
    """One compiled Monte Carlo run: the kernel called chunk by chunk on the model."""

    def __init__(
        self,
        mdp: FiniteMDP,
        model: Model,
        behaviour: Behaviour,
        settings: MCSettings,
        run: _MCRun,
        rng: NDArray[np.uint64],
        keeps_v: bool,
    ) -> None:
        self.mdp, self.model, self.behaviour, self.settings = mdp, model, behaviour, settings
        self.run, self.rng, self.keeps_v, self.truncated = run, rng, keeps_v, 0

    def __call__(self, k0: int, k1: int) -> int:
        steps, truncated = _mc_chunk(
            self.model, self.behaviour, self.settings, self.run, self.rng, k0, k1
        )
        self.truncated += truncated
        return int(steps)

    def estimate(self) -> tuple[Any, Any, None]:
        return self.run.q, self.run.tables.v, None

    def outcome(self) -> dict[str, Any]:
        return _outcome(self.run, self.mdp.states, self.mdp, self.truncated, self.keeps_v)


# =============================================================================== general path
class _EnvRun:
    """The general path: a plain Python loop over ``env.reset`` / ``env.step``.

    It chooses actions with the compiled :func:`choose_action` and updates with
    :func:`mc_episode_update`, with the same RNG state as the fast path, so on a
    deterministic MDP both give the same numbers.
    """

    def __init__(
        self,
        env: Any,
        mdp: FiniteMDP | None,
        st: _Setup,
        gamma: float,
        rng: NDArray[np.uint64],
        gen: np.random.Generator,
        episodes: int,
        max_steps: int,
        name: str,
    ) -> None:
        A = int(env.action_space.n)
        base_mdp = getattr(getattr(env, "unwrapped", env), "mdp", None)
        self.own_model = False
        if mdp is not None:
            if mdp.n_actions != A:
                raise InvalidArgumentError(
                    f"the model {mdp.name!r} has {mdp.n_actions} actions but the env has {A}"
                )
            self.own_model = base_mdp is mdp
            own = self.own_model
            index = StateIndex.discrete(mdp.n_states) if own else StateIndex.of_labels(mdp.states)
            self.mask = writable(mdp.action_mask, np.bool_)
        else:
            index = StateIndex.for_env(env)
            self.mask = np.ones((max(len(index), 1), A), dtype=np.bool_)
        if st.exploring_starts and base_mdp is None:
            raise InvalidArgumentError(
                "exploring starts need an env that can start in a chosen state: a FiniteMDP or "
                "policylab's MDPEnv (Gymnasium envs in general cannot be reset to a state)"
            )
        S0 = max(len(index), 1)
        self.env, self.mdp, self.st, self.index, self.rng = env, mdp, st, index, rng
        self.run = _mc_run(S0, A, max_steps, episodes)
        self.max_steps, self.truncated = max_steps, 0
        self.keeps_v = _keeps_v(st.kind, st.truth_kind)
        policy = st.policy
        fixed = st.policy_kind == FIXED_POLICY
        self.pi_table = (
            writable(policy.probs, np.float64) if fixed and hasattr(policy, "probs") else None
        )
        target = st.target
        tgt = writable(target.probs.ravel(), np.float64) if target is not None else np.zeros(S0 * A)
        self.settings = MCSettings(
            gamma, st.kind, st.first_visit, st.alpha.params, st.weighted, tgt
        )
        self.no_row = np.zeros(A)
        self.seen = np.zeros(S0, dtype=bool)
        self.terminal = writable(mdp.terminal, np.bool_) if mdp is not None else None
        self.env_seed: int | None = int(gen.integers(2**31 - 1))

    def __call__(self, k0: int, k1: int) -> int:
        st, index, rng, env = self.st, self.index, self.rng, self.env
        A = self.no_row.shape[0]
        steps = 0
        for k in range(k0, k1):
            options = None
            if st.exploring_starts:
                assert self.terminal is not None and self.mdp is not None
                options = {"state": self.mdp.states[exploring_start_state(self.terminal, rng)]}
            obs, _ = env.reset(seed=self.env_seed, options=options)
            self.env_seed = None
            eps = schedule_value(st.epsilon.params, k + 1.0)
            T, cut = 0, False
            run = self.run
            while True:  # one episode: S_0, A_0, R_1, ..., S_T
                s = index(obs)
                if s >= len(self.seen):
                    run = self.run = _grow(run, s + 1)
                    self.seen = _grow_flat(self.seen, run.q.shape[0])
                    self.mask = grow_rows(self.mask, run.q.shape[0], fill=True)
                self.seen[s] = True
                run.buf.s[T] = s
                if self.max_steps <= T:
                    cut = True
                    break
                if self.pi_table is not None:
                    pi_row = self.pi_table[s]
                elif st.policy_kind == FIXED_POLICY:
                    pi_row = _policy_row(st.policy, obs, A)
                else:
                    pi_row = self.no_row
                e = behaviour_epsilon(st.eps_by_state, st.epsilon.params, eps, run.tables.nv[s])
                explore = st.exploring_starts and T == 0
                a, b = choose_action(
                    st.policy_kind, explore, pi_row, run.q[s], self.mask[s], e, rng
                )
                obs, r, term, trunc, _ = env.step(a)
                run.buf.a[T], run.buf.r[T], run.buf.b[T] = a, float(r), b
                T += 1
                if term or trunc:
                    cut = bool(trunc) and not term
                    break
            steps += T
            run.lengths[k] = T
            run.returns[k] = episode_return(run.buf.r, T, self.settings.gamma)
            if cut:
                self.truncated += 1
                continue
            mc_episode_update(self.settings, run.tables, run.buf, run.scratch, self.mask, T, k + 1)
        return steps

    def estimate(self) -> tuple[Any, Any, Any]:
        # an env over its own FiniteMDP can reach every state: score them all, as the
        # compiled path does; with an outside model score only the states seen so far
        n = len(self.index)
        return self.run.q[:n], self.run.tables.v[:n], None if self.own_model else self.seen[:n]

    def outcome(self) -> dict[str, Any]:
        return _outcome(self.run, self.index.labels, self.mdp, self.truncated, self.keeps_v)


def _policy_row(policy: Any, obs: Any, A: int) -> NDArray[np.float64]:
    """pi(. | obs) from a callable policy of the general path, checked."""
    row = np.asarray(policy(obs), dtype=np.float64)
    if row.shape != (A,) or np.any(row < 0) or abs(row.sum() - 1.0) > 1e-8:
        raise InvalidPolicyError(
            f"the policy function must return {A} probabilities summing to 1 for observation "
            f"{obs!r}; got {row!r}"
        )
    return row


# =============================================================================== the entries
def _fixed_policy(
    problem: Any, policy: Any, model: FiniteMDP | None, what: str
) -> tuple[Any, Policy | None]:
    """(policy for episode generation, Policy over the model for the ground truth)."""
    from policylab.mdp.policy import Policy

    mdp = problem if is_finite_mdp(problem) else model
    if mdp is None and not is_finite_mdp(problem):
        env = as_env(problem)
        mdp = getattr(getattr(env, "unwrapped", env), "mdp", None)
    if policy is None:
        if mdp is None:
            raise InvalidArgumentError(
                f"{what}: give a policy (a function obs -> action probabilities) for an env "
                "without a model"
            )
        pol = Policy.uniform(mdp)
        return pol, pol
    if isinstance(policy, Policy):
        if mdp is not None and (policy.states != mdp.states or policy.actions != mdp.actions):
            raise InvalidPolicyError(
                f"{what}: the policy's states/actions do not match the problem {mdp.name!r}"
            )
        return policy, policy
    if callable(policy):
        if mdp is not None:
            raise InvalidArgumentError(
                f"{what}: with a known model pass a policylab Policy (needed for the exact v_pi)"
            )
        return policy, None
    raise InvalidPolicyError(
        f"{what}: policy must be a Policy or a callable; got {type(policy).__name__}"
    )


def _setup_prediction(args: dict[str, Any]) -> _Setup:
    """mc-prediction: first- or every-visit averages of the returns under a fixed policy."""
    policy, truth_policy = _fixed_policy(
        args["problem"], args["policy"], args["model"], "mc_prediction"
    )
    a = as_schedule(args["alpha"], Schedule.inverse(), "alpha").check_range(0.0, 1.0, "alpha")
    first_visit = bool(args["first_visit"])
    return _Setup(
        AVERAGE, policy, FIXED_POLICY, Schedule.constant(0.0), False, False, first_visit, a,
        False, None, "prediction", truth_policy, args["error_on"],
        {"first_visit": first_visit, "alpha": str(a)},
    )  # fmt: skip


def _setup_control(args: dict[str, Any]) -> _Setup:
    """mc-control: exploring starts, or epsilon-greedy with a GLIE schedule."""
    epsilon, epsilon_by, exploring = args["epsilon"], args["epsilon_by"], args["exploring_starts"]
    if epsilon_by is None:
        epsilon_by = "state" if epsilon is None else "episode"
    if epsilon_by not in ("episode", "state"):
        raise InvalidArgumentError(f"epsilon_by must be 'episode' or 'state'; got {epsilon_by!r}")
    if exploring and epsilon is not None:
        raise InvalidArgumentError("exploring starts act greedily; do not give epsilon with them")
    eps = as_schedule(epsilon, Schedule.inverse(power=0.5), "epsilon")
    if epsilon_by == "episode":
        eps.check_range(0.0, 1.0, "epsilon")
    elif min(eps.a, eps.c) < 0:
        raise InvalidArgumentError(f"epsilon must be >= 0; schedule {eps} is negative")
    if exploring:
        eps = Schedule.constant(0.0)
    a = as_schedule(args["alpha"], Schedule.inverse(), "alpha").check_range(0.0, 1.0, "alpha")
    first_visit = bool(args["first_visit"])
    params = {
        "epsilon_by": epsilon_by,
        "exploring_starts": bool(exploring),
        "epsilon": str(eps),
        "alpha": str(a),
        "first_visit": first_visit,
    }
    return _Setup(
        AVERAGE, None, EPSILON_GREEDY, eps, epsilon_by == "state", bool(exploring),
        first_visit, a, False, None, "control", None, "q", params,
    )  # fmt: skip


def _setup_off_policy(args: dict[str, Any]) -> _Setup:
    """mc-off-policy: importance sampling, prediction of a target or greedy control."""
    from policylab.mdp.policy import Policy

    target, epsilon = args["target"], args["epsilon"]
    if target is not None and not isinstance(target, Policy):
        raise InvalidPolicyError(
            f"target must be a policylab Policy or None; got {type(target).__name__}"
        )
    if target is not None and epsilon is not None:
        raise InvalidArgumentError(
            "epsilon (an epsilon-greedy behaviour) is for control; give behavior= instead"
        )
    policy_kind = FIXED_POLICY
    eps = Schedule.constant(0.0)
    policy: Any = None
    if epsilon is not None:
        policy_kind = EPSILON_GREEDY
        eps = as_schedule(epsilon, Schedule.inverse(), "epsilon").check_range(0.0, 1.0, "epsilon")
        if eps.kind == CONSTANT and eps.a == 0.0:
            raise InvalidArgumentError("an epsilon-greedy behaviour needs epsilon > 0 (coverage)")
    else:
        what = "mc_off_policy behavior"
        policy, _ = _fixed_policy(args["problem"], args["behavior"], args["model"], what)
        if target is not None and isinstance(policy, Policy):
            _check_coverage(target, policy)
        elif target is None and isinstance(policy, Policy):
            _check_soft(policy)
    weighted, first_visit = bool(args["weighted"]), bool(args["first_visit"])
    params = {
        "weighted": weighted,
        "first_visit": first_visit,
        "target": "greedy" if target is None else "given",
        "behavior": f"epsilon-greedy {eps}" if epsilon is not None else "fixed",
    }
    return _Setup(
        IS_PREDICTION if target is not None else IS_CONTROL, policy, policy_kind, eps, False,
        False, first_visit, Schedule.inverse(), weighted, target,
        "prediction" if target is not None else "control", target,
        args["error_on"] if target is not None else "q", params,
    )  # fmt: skip


MC_ENTRIES = (
    MCEntry("mc-prediction", _setup_prediction),
    MCEntry("mc-control", _setup_control),
    MCEntry("mc-off-policy", _setup_off_policy),
)
add_entries(MC_ENTRIES)


# =============================================================================== learners
def mc_prediction(
    problem: FiniteMDP | Any,
    policy: Policy | Callable[[Any], Any] | None = None,
    *,
    episodes: int = 10_000,
    first_visit: bool = True,
    alpha: Schedule | float | str | None = None,
    error_on: Literal["v", "q"] = "q",
    start: Hashable | None = None,
    score: bool = True,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Monte Carlo prediction of v_pi and q_pi (first-visit or every-visit).

    For each episode S_0, A_0, R_1, ..., S_T generated by pi, backwards from t = T - 1:
    G_t = R_{t+1} + gamma G_{t+1}; N(S_t, A_t) += 1; Q(S_t, A_t) += (G_t - Q) / N (and
    the same for V(S_t)): Q and V are the running means of the returns after each
    (first) visit. ``result.policy`` is the greedy policy of the Q-table. Episodes
    truncated at ``max_steps`` are counted (``result.truncated``), not averaged.

    Args:
        problem: A FiniteMDP (compiled path) or a Gymnasium env / id (Python loop).
        policy: The policy to evaluate: a :class:`~policylab.Policy` (default: the
            equiprobable random policy), or for an env without model a function from an
            observation to the (A,) action probabilities.
        episodes: Number of episodes.
        first_visit: First-visit MC (True) or every-visit MC (False).
        alpha: Step size: None for the sample average 1/N, a constant (constant-alpha
            MC) or a :class:`Schedule` of the visit count.
        error_on: Score Q against q_pi (``"q"``) or V against v_pi (``"v"``).
        start: Optional start state label (FiniteMDP only).
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).
        **options: The options every tabular learner shares
            (:class:`~policylab.tabular.LearnOptions`): ``gamma``, ``seed``,
            ``checkpoints``, ``max_steps``, ``model`` (for an env, e.g.
            ``pl.problems.blackjack()`` for Gymnasium's Blackjack-v1), ``progress``.

    Returns:
        The :class:`LearnResult` (error against v_pi / q_pi where the model is known).
    """
    return learn_entry("mc-prediction", locals())


def mc_control(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 100_000,
    exploring_starts: bool = False,
    epsilon: Schedule | float | str | None = None,
    epsilon_by: Literal["episode", "state"] | None = None,
    alpha: Schedule | float | str | None = None,
    first_visit: bool = True,
    start: Hashable | None = None,
    score: bool = True,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """On-policy Monte Carlo control: exploring starts or epsilon-greedy (GLIE).

    Policy evaluation and improvement alternate episode by episode: each episode is
    generated by the current policy (greedy in Q with exploring starts; epsilon-greedy
    in Q otherwise), then Q(S_t, A_t) moves towards the returns G_t as in
    :func:`mc_prediction`. With epsilon -> 0 while every pair is still tried infinitely
    often (GLIE) and sample averages, Q converges to q*. The default schedule is GLIE
    state by state: epsilon = 1/sqrt(n(s)) at the n-th visit of s, so that rare states
    keep exploring while common ones turn greedy (on Blackjack, 1M episodes: 95 % of
    the states optimal, against 70 % for the textbook epsilon_k = 1/k of the episode
    number, which stops exploring after a few hundred episodes).

    Episodes truncated at ``max_steps`` are not used. On a deterministic task a greedy
    policy (exploring starts, small epsilon) can loop for ever: such episodes run to
    the limit and teach nothing (Monte Carlo needs episodes that end; Sutton & Barto
    section 5.3), so keep the limit small there and check ``result.truncated``.

    Args:
        problem: A FiniteMDP (compiled path) or a Gymnasium env / id (Python loop).
        episodes: Number of episodes.
        exploring_starts: Start each episode in a uniform state with a uniform first
            action, then act greedily (Sutton & Barto's Monte Carlo ES). Needs a
            FiniteMDP or policylab's MDPEnv.
        epsilon: Exploration schedule (without exploring starts): default
            1/sqrt(n(s)) by state visits; a number for a constant epsilon; a
            :class:`Schedule` (``Schedule.inverse()`` with ``epsilon_by="episode"`` is
            the textbook epsilon_k = 1/k).
        epsilon_by: What the schedule counts: ``"episode"`` (epsilon_k of the episode
            number k) or ``"state"`` (epsilon of the number of visits of the current
            state, capped at 1). Default: ``"state"`` for the default schedule,
            ``"episode"`` for a schedule given.
        alpha: Step size: None for sample averages 1/N, a constant for
            constant-alpha MC, or a :class:`Schedule` of the visit count.
        first_visit: First-visit (True) or every-visit (False) updates.
        start: Optional start state label (FiniteMDP only, without exploring starts).
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).
        **options: The options every tabular learner shares
            (:class:`~policylab.tabular.LearnOptions`): ``gamma``, ``seed``,
            ``checkpoints``, ``max_steps``, ``model``, ``progress``.

    Returns:
        The :class:`LearnResult`; its error is measured against q*.
    """
    return learn_entry("mc-control", locals())


def mc_off_policy(
    problem: FiniteMDP | Any,
    target: Policy | None = None,
    *,
    behavior: Policy | Callable[[Any], Any] | None = None,
    epsilon: Schedule | float | str | None = None,
    weighted: bool = False,
    episodes: int = 100_000,
    first_visit: bool = False,
    error_on: Literal["v", "q"] = "q",
    start: Hashable | None = None,
    score: bool = True,
    **options: Unpack[LearnOptions],
) -> LearnResult:
    """Off-policy Monte Carlo by importance sampling, ordinary or weighted.

    Episodes come from a behaviour policy b; returns are reweighted by the importance
    sampling ratio rho_{t:T-1} = prod_k pi(A_k | S_k) / b(A_k | S_k). Ordinary IS
    averages rho G over all visits (unbiased, possibly huge variance); weighted IS
    divides by the sum of the ratios instead (biased, consistent, low variance).
    Episodes truncated at ``max_steps`` are not used.

    * Prediction (``target`` given): estimates v_pi and q_pi of the target policy.
    * Control (``target=None``): the target is the greedy policy of Q, improved as Q
      is updated (Sutton & Barto section 5.7); the error is against q*.

    Args:
        problem: A FiniteMDP (compiled path) or a Gymnasium env / id (Python loop).
        target: The policy to evaluate, or None for control.
        behavior: The behaviour policy b (default: equiprobable random); it must give
            every action the target may take a positive probability (coverage).
        epsilon: For control only: behave epsilon-greedily in the current Q with this
            schedule instead of with a fixed b.
        weighted: Weighted (True) or ordinary (False) importance sampling.
        episodes: Number of episodes.
        first_visit: First-visit (True) or every-visit (False, the book's choice).
        error_on: For prediction: score Q (``"q"``) or V (``"v"``).
        start: Optional start state label (FiniteMDP only).
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).
        **options: The options every tabular learner shares
            (:class:`~policylab.tabular.LearnOptions`): ``gamma``, ``seed``,
            ``checkpoints``, ``max_steps``, ``model``, ``progress``.

    Returns:
        The :class:`LearnResult`.
    """
    return learn_entry("mc-off-policy", locals())


def _check_coverage(target: Policy, behavior: Policy) -> None:
    bad = (target.probs > 0) & (behavior.probs <= 0)
    if np.any(bad):
        s, a = map(int, np.argwhere(bad)[0])
        raise InvalidPolicyError(
            f"coverage fails: the target takes action {target.actions[a]!r} in state "
            f"{target.states[s]!r} but the behaviour policy never does; b(a | s) must be > 0 "
            "wherever pi(a | s) > 0"
        )


def _check_soft(behavior: Policy) -> None:
    bad = behavior.mask & (behavior.probs <= 0)
    if np.any(bad):
        s, a = map(int, np.argwhere(bad)[0])
        raise InvalidPolicyError(
            f"off-policy control needs a soft behaviour policy (b(a | s) > 0 for every available "
            f"action); b({behavior.actions[a]!r} | {behavior.states[s]!r}) = 0"
        )


# =============================================================================== registry
_EVERY_VISIT = Option(
    "--every-visit",
    "first_visit",
    "flag",
    "Every-visit MC: average the returns after every visit, not only the first.",
    value_if_set=False,
)
register_algorithm(
    "mc-prediction",
    mc_prediction,
    "Monte Carlo prediction of v_pi and q_pi (notes section 6): average the returns after visits.",
    options=(
        _EVERY_VISIT,
        Option(
            "--alpha",
            "alpha",
            "schedule",
            "Step size: default 1/n (sample average); a number for constant-alpha MC, or "
            "exp:START,DECAY[,FLOOR], linear:START,END,STEPS.",
        ),
    ),
    kind="prediction",
    default_episodes=10_000,
)
register_algorithm(
    "mc-control",
    mc_control,
    "On-policy Monte Carlo control: exploring starts, or epsilon-greedy with a GLIE schedule.",
    options=(
        Option(
            "--exploring-starts",
            "exploring_starts",
            "flag",
            "Monte Carlo ES: uniform first state and action, then greedy.",
        ),
        Option(
            "--epsilon",
            "epsilon",
            "schedule",
            "Exploration: default 1/sqrt(n(s)) over the visits of each state (GLIE); a number "
            "for a constant epsilon, or 1/n, exp:START,DECAY[,FLOOR], linear:START,END,STEPS "
            "(counted in episodes unless --epsilon-by state).",
        ),
        Option(
            "--epsilon-by",
            "epsilon_by",
            "str",
            "What the epsilon schedule counts: 'episode' or 'state' (visits of the current "
            "state); default: state for the default schedule, episode for a given one.",
        ),
        Option(
            "--alpha",
            "alpha",
            "schedule",
            "Step size: default 1/n (sample average); a number for constant-alpha MC.",
        ),
        _EVERY_VISIT,
    ),
    kind="control",
    default_episodes=100_000,
)
register_algorithm(
    "mc-off-policy",
    mc_off_policy,
    "Off-policy Monte Carlo by importance sampling: prediction of --target, else greedy control.",
    options=(
        Option(
            "--weighted", "weighted", "flag", "Weighted importance sampling (default: ordinary)."
        ),
        Option(
            "--target",
            "target",
            "policy",
            "Target policy to evaluate ('uniform' or a named policy of the problem); default: "
            "control of the greedy policy.",
        ),
        Option(
            "--epsilon",
            "epsilon",
            "schedule",
            "Control only: behave epsilon-greedily in Q (default: the equiprobable policy).",
        ),
        Option("--first-visit", "first_visit", "flag", "First-visit (default: every-visit)."),
    ),
    kind="control",
    default_episodes=100_000,
)
