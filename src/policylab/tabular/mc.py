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

import contextvars
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numba as nb
import numpy as np
from numba import prange

from policylab.exceptions import InvalidArgumentError, InvalidPolicyError
from policylab.tabular.common import (
    Recorder,
    StateIndex,
    as_env,
    check_episodes,
    check_gamma,
    checkpoint_episodes,
    env_name,
    grow_rows,
    is_finite_mdp,
    progress_bar,
    start_state,
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
    exploring_start_state,
    generate_episode,
    rng_states,
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
from policylab.validation import as_generator

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


@nb.njit(cache=True, nogil=True)
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
def _run_of(x: _Stack, r: int) -> _MCRun:  # pragma: no cover - compiled
    """Run r of stacked runs (views of its slices)."""
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
    and its RNG stream ``rngs[r]``, so its numbers are those of the run alone.
    """
    n_runs = rngs.shape[0]
    out = np.zeros((n_runs, 2), dtype=np.int64)
    for r in prange(n_runs):
        steps, truncated = _mc_chunk(
            model, behaviour, settings, _run_of(runs, r), rngs[r], 0, episodes
        )
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


# =============================================================================== driver
def _run(
    algorithm: str,
    problem: Any,
    *,
    kind: int,
    episodes: int,
    seed: Seed,
    gamma: float | None,
    policy: Policy | Callable[[Any], Any] | None,
    policy_kind: int,
    epsilon: Schedule,
    exploring_starts: bool,
    eps_by_state: bool,
    first_visit: bool,
    alpha: Schedule,
    weighted: bool,
    target: Policy | None,
    truth_kind: Literal["prediction", "control"],
    truth_policy: Policy | None,
    error_on: Literal["v", "q"],
    checkpoints: int,
    max_steps: int,
    start: Hashable | None,
    progress: bool,
    model: FiniteMDP | None,
    params: dict[str, Any],
    score: bool = True,
) -> LearnResult:
    """Shared body of the three learners: fast path on a FiniteMDP, else the env loop."""
    episodes = check_episodes(episodes)
    max_steps = check_episodes(max_steps, "max_steps")
    ckpts = checkpoint_episodes(episodes, checkpoints)
    mdp: FiniteMDP | None
    if is_finite_mdp(problem):
        mdp = problem
        env = None
    else:
        env = as_env(problem)
        mdp = model if model is not None else getattr(getattr(env, "unwrapped", env), "mdp", None)
        if start is not None:
            raise InvalidArgumentError(
                "start= is only supported on a FiniteMDP; reset the env instead"
            )
    g = check_gamma(gamma, mdp.gamma if mdp is not None else 1.0)
    if mdp is not None and not mdp.terminal.any():
        raise InvalidArgumentError(
            f"Monte Carlo needs an episodic task; {mdp.name!r} has no terminal state (use a TD "
            "method for continuing tasks)"
        )
    if env is None and _PLAN.get():  # seed_study asks for the compiled run, not a result
        assert mdp is not None  # the compiled path always has a model
        model_, behaviour, settings = _fast_setup(
            mdp, policy, policy_kind, epsilon, eps_by_state, exploring_starts, start,
            kind, g, first_visit, alpha, weighted, target,
        )  # fmt: skip
        raise _Planned(
            _Plan(
                algorithm, mdp, model_, behaviour, settings, episodes, max_steps,
                _keeps_v(kind, truth_kind),
            )
        )  # fmt: skip
    truth: GroundTruth | None = None
    if mdp is not None and score:
        if truth_kind == "prediction":
            assert truth_policy is not None  # set by the callers, never from user input
            truth = GroundTruth.prediction(mdp, truth_policy, on=error_on, gamma=g)
        else:
            truth = GroundTruth.control(mdp, on=error_on, gamma=g)
    rec = Recorder(truth, ckpts)
    gen = as_generator(seed)
    rng = rng_states(gen, 1)[0]
    t0 = time.perf_counter()
    if env is None and mdp is not None:
        model_, behaviour, settings = _fast_setup(
            mdp, policy, policy_kind, epsilon, eps_by_state, exploring_starts, start,
            kind, g, first_visit, alpha, weighted, target,
        )  # fmt: skip
        run = _mc_run(mdp.n_states, mdp.n_actions, max_steps, episodes)
        steps = truncated = 0
        with progress_bar(progress, episodes, algorithm) as advance:
            for k0, k1 in rec.chunks():
                st, tr = _mc_chunk(model_, behaviour, settings, run, rng, k0, k1)
                steps += st
                truncated += tr
                rec.record(run.q, run.tables.v)
                advance(k1 - k0)
        index_labels: tuple[Hashable, ...] = mdp.states
    else:
        run, steps, truncated, index_labels = _run_env(
            env,
            mdp,
            rec,
            rng,
            gen,
            episodes=episodes,
            policy=policy,
            behaviour=Behaviour(
                policy_kind, np.zeros((0, 0)), epsilon.params, eps_by_state, exploring_starts
            ),
            settings=MCSettings(g, kind, first_visit, alpha.params, weighted, np.zeros(0)),
            target=target,
            max_steps=max_steps,
            progress=progress,
            name=algorithm,
        )
    seconds = time.perf_counter() - t0
    S = len(index_labels)
    if mdp is not None:
        mask = np.asarray(mdp.action_mask, dtype=bool)
        terminal = np.asarray(mdp.terminal, dtype=bool)
        actions = mdp.actions
    else:
        mask = np.ones((S, run.q.shape[1]), dtype=bool)
        terminal = np.zeros(S, dtype=bool)
        actions = tuple(range(run.q.shape[1]))
    q, v = _q_and_v(run.q[:S], run.tables.v[:S], mask, terminal, _keeps_v(kind, truth_kind))
    return LearnResult(
        algorithm=algorithm,
        problem=mdp.name if mdp is not None else env_name(env),
        states=tuple(index_labels),
        actions=tuple(actions),
        q=q,
        v=v,
        policy=greedy_probs(q, mask),
        terminal=terminal,
        action_mask=mask,
        counts=run.tables.nq[: S * q.shape[1]].reshape(S, q.shape[1]).copy(),
        episodes=episodes,
        steps=int(steps),
        seconds=seconds,
        episode_returns=run.returns,
        truncated=int(truncated),
        episode_lengths=run.lengths,
        params={
            **params,
            "gamma": g,
            "seed": seed if isinstance(seed, (int, np.integer)) else None,
            "path": "compiled" if env is None else "gymnasium",
        },
        mdp=mdp,
        **rec.arrays(),
    )


def _keeps_v(kind: int, truth_kind: str) -> bool:
    """Whether V is learned itself (prediction) rather than read off Q as max_a Q."""
    return (kind == AVERAGE and truth_kind == "prediction") or kind == IS_PREDICTION


def _q_and_v(
    q: NDArray[np.float64],
    v_learned: NDArray[np.float64],
    mask: NDArray[np.bool_],
    terminal: NDArray[np.bool_],
    keeps_v: bool,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The result's Q (0 off A(s)) and V (learned, or max over A(s) of Q; 0 if terminal)."""
    q = np.where(mask, q, 0.0)
    if keeps_v:
        v = v_learned.copy()
    else:
        v = np.where(mask, q, -np.inf).max(axis=1)
        v[~mask.any(axis=1)] = 0.0
    v[terminal] = 0.0
    return q, v


def _fast_setup(
    mdp: FiniteMDP,
    policy: Any,
    policy_kind: int,
    epsilon: Schedule,
    eps_by_state: bool,
    exploring_starts: bool,
    start: Hashable | None,
    kind: int,
    gamma: float,
    first_visit: bool,
    alpha: Schedule,
    weighted: bool,
    target: Policy | None,
) -> tuple[Model, Behaviour, MCSettings]:
    """The compiled path's model, behaviour and update settings."""
    km = KernelMDP.of(mdp, gamma)
    S, A = mdp.n_states, mdp.n_actions
    pi = writable(policy.probs if policy_kind == FIXED_POLICY else np.zeros((S, A)), np.float64)
    tgt = writable(target.probs.ravel() if target is not None else np.zeros(S * A), np.float64)
    initial = writable(start_state(mdp, start), np.float64)
    model = Model(
        km.indptr, km.next_states, km.probs, km.rewards, km.terminal, initial, km.mask
    )  # fmt: skip
    behaviour = Behaviour(policy_kind, pi, epsilon.params, eps_by_state, exploring_starts)
    return model, behaviour, MCSettings(gamma, kind, first_visit, alpha.params, weighted, tgt)


@dataclass(frozen=True)
class _Plan:
    """A compiled Monte Carlo run, set up but not run (what :func:`seed_study` runs)."""

    algorithm: str
    mdp: FiniteMDP
    model: Model
    behaviour: Behaviour
    settings: MCSettings
    episodes: int
    max_steps: int
    keeps_v: bool


class _Planned(Exception):  # noqa: N818  (not an error: carries the plan out of a learner)
    """Raised by a learner called under :func:`planned_run` instead of running."""

    def __init__(self, plan: _Plan) -> None:
        super().__init__(plan.algorithm)
        self.plan = plan


_PLAN: contextvars.ContextVar[bool] = contextvars.ContextVar("_PLAN", default=False)


def planned_run(learner: Callable[..., Any], problem: Any, **kwargs: Any) -> _Plan:
    """The compiled run a Monte Carlo learner call would make, checked but not run."""
    token = _PLAN.set(True)
    try:
        learner(problem, **kwargs)
    except _Planned as planned:
        return planned.plan
    finally:
        _PLAN.reset(token)
    raise InvalidArgumentError("seed_study runs Monte Carlo learners on a FiniteMDP only")


def many_mc_runs(
    plan: _Plan, rngs: NDArray[np.uint64], workers_limited: bool = False
) -> tuple[_MCRun, NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Run ``plan`` once per RNG state in one parallel compiled call.

    Returns the stacked runs, (R, 2) steps and truncated episodes, and the (R, S, A) Q
    and (R, S) V of the results.
    """
    mdp = plan.mdp
    S, A, R = mdp.n_states, mdp.n_actions, rngs.shape[0]
    runs = _mc_run(S, A, plan.max_steps, plan.episodes, n_runs=R)
    counts = _many_mc_runs(
        plan.model, plan.behaviour, plan.settings, _stack(runs), rngs, plan.episodes
    )
    mask = np.asarray(mdp.action_mask, dtype=bool)
    terminal = np.asarray(mdp.terminal, dtype=bool)
    qv = [_q_and_v(runs.q[r], runs.tables.v[r], mask, terminal, plan.keeps_v) for r in range(R)]
    return runs, counts, np.stack([q for q, _ in qv]), np.stack([v for _, v in qv])


# =============================================================================== general path
def _run_env(
    env: Any,
    mdp: FiniteMDP | None,
    rec: Recorder,
    rng: NDArray[np.uint64],
    gen: np.random.Generator,
    *,
    episodes: int,
    policy: Any,
    behaviour: Behaviour,
    settings: MCSettings,
    target: Policy | None,
    max_steps: int,
    progress: bool,
    name: str,
) -> tuple[_MCRun, int, int, tuple[Hashable, ...]]:
    """The general path: a plain Python loop over ``env.reset`` / ``env.step``.

    It chooses actions with the compiled :func:`choose_action` and updates with
    :func:`mc_episode_update`, with the same RNG state as the fast path, so on a
    deterministic MDP both give the same numbers.
    """
    A = int(env.action_space.n)
    own_model = False
    if mdp is not None:
        if mdp.n_actions != A:
            raise InvalidArgumentError(
                f"the model {mdp.name!r} has {mdp.n_actions} actions but the env has {A}"
            )
        own_model = getattr(getattr(env, "unwrapped", env), "mdp", None) is mdp
        n_model = mdp.n_states
        index = StateIndex.discrete(n_model) if own_model else StateIndex.of_labels(mdp.states)
        mask = writable(mdp.action_mask, np.bool_)
    else:
        index = StateIndex.for_env(env)
        mask = np.ones((max(len(index), 1), A), dtype=np.bool_)
    if behaviour.exploring_starts and getattr(getattr(env, "unwrapped", env), "mdp", None) is None:
        raise InvalidArgumentError(
            "exploring starts need an env that can start in a chosen state: a FiniteMDP or "
            "policylab's MDPEnv (Gymnasium envs in general cannot be reset to a state)"
        )
    S0 = max(len(index), 1)
    run = _mc_run(S0, A, max_steps, episodes)
    pi_table = (
        writable(policy.probs, np.float64)
        if (behaviour.kind == FIXED_POLICY and hasattr(policy, "probs"))
        else None
    )
    tgt = writable(target.probs.ravel(), np.float64) if target is not None else np.zeros(S0 * A)
    settings = settings._replace(target=tgt)
    no_row = np.zeros(A)
    kind, by_state, eps_params = behaviour.kind, behaviour.by_state, behaviour.epsilon
    seen = np.zeros(S0, dtype=bool)
    terminal_ = writable(mdp.terminal, np.bool_) if mdp is not None else None
    env_seed: int | None = int(gen.integers(2**31 - 1))
    steps = truncated = 0
    with progress_bar(progress, episodes, name) as advance:
        for k0, k1 in rec.chunks():
            for k in range(k0, k1):
                options = None
                if behaviour.exploring_starts:
                    assert terminal_ is not None and mdp is not None
                    options = {"state": mdp.states[exploring_start_state(terminal_, rng)]}
                obs, _ = env.reset(seed=env_seed, options=options)
                env_seed = None
                eps = schedule_value(behaviour.epsilon, k + 1.0)
                T, cut = 0, False
                while True:  # one episode: S_0, A_0, R_1, ..., S_T
                    s = index(obs)
                    if s >= len(seen):
                        run = _grow(run, s + 1)
                        seen = _grow_flat(seen, run.q.shape[0])
                        mask = grow_rows(mask, run.q.shape[0], fill=True)
                    seen[s] = True
                    run.buf.s[T] = s
                    if max_steps <= T:
                        cut = True
                        break
                    if pi_table is not None:
                        pi_row = pi_table[s]
                    elif behaviour.kind == FIXED_POLICY:
                        pi_row = _policy_row(policy, obs, A)
                    else:
                        pi_row = no_row
                    e = behaviour_epsilon(by_state, eps_params, eps, run.tables.nv[s])
                    explore = behaviour.exploring_starts and T == 0
                    a, b = choose_action(kind, explore, pi_row, run.q[s], mask[s], e, rng)
                    obs, r, term, trunc, _ = env.step(a)
                    run.buf.a[T], run.buf.r[T], run.buf.b[T] = a, float(r), b
                    T += 1
                    if term or trunc:
                        cut = bool(trunc) and not term
                        break
                steps += T
                run.lengths[k] = T
                run.returns[k] = episode_return(run.buf.r, T, settings.gamma)
                if cut:
                    truncated += 1
                    continue
                mc_episode_update(settings, run.tables, run.buf, run.scratch, mask, T, k + 1)
            n = len(index)
            # an env over its own FiniteMDP can reach every state: score them all, as the
            # compiled path does; with an outside model score only the states seen so far
            rec.record(run.q[:n], run.tables.v[:n], None if own_model else seen[:n])
            advance(k1 - k0)
    return run, steps, truncated, index.labels


def _policy_row(policy: Any, obs: Any, A: int) -> NDArray[np.float64]:
    """pi(. | obs) from a callable policy of the general path, checked."""
    row = np.asarray(policy(obs), dtype=np.float64)
    if row.shape != (A,) or np.any(row < 0) or abs(row.sum() - 1.0) > 1e-8:
        raise InvalidPolicyError(
            f"the policy function must return {A} probabilities summing to 1 for observation "
            f"{obs!r}; got {row!r}"
        )
    return row


# =============================================================================== learners
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


def mc_prediction(
    problem: FiniteMDP | Any,
    policy: Policy | Callable[[Any], Any] | None = None,
    *,
    episodes: int = 10_000,
    first_visit: bool = True,
    alpha: Schedule | float | str | None = None,
    gamma: float | None = None,
    seed: Seed = None,
    checkpoints: int = 50,
    error_on: Literal["v", "q"] = "q",
    max_steps: int = 10_000,
    start: Hashable | None = None,
    model: FiniteMDP | None = None,
    progress: bool = False,
    score: bool = True,
) -> LearnResult:
    """Monte Carlo prediction of v_pi and q_pi (first-visit or every-visit).

    For each episode S_0, A_0, R_1, ..., S_T generated by pi, backwards from t = T - 1:
    G_t = R_{t+1} + gamma G_{t+1}; N(S_t, A_t) += 1; Q(S_t, A_t) += (G_t - Q) / N (and
    the same for V(S_t)): Q and V are the running means of the returns after each
    (first) visit. ``result.policy`` is the greedy policy of the Q-table.

    Args:
        problem: A FiniteMDP (compiled path) or a Gymnasium env / id (Python loop).
        policy: The policy to evaluate: a :class:`~policylab.Policy` (default: the
            equiprobable random policy), or for an env without model a function from an
            observation to the (A,) action probabilities.
        episodes: Number of episodes.
        first_visit: First-visit MC (True) or every-visit MC (False).
        alpha: Step size: None for the sample average 1/N, a constant (constant-alpha
            MC) or a :class:`Schedule` of the visit count.
        gamma: Discount rate (default: the problem's).
        seed: Seed or Generator; same seed, same result.
        checkpoints: About how many points of the error curve (log-spaced).
        error_on: Score Q against q_pi (``"q"``) or V against v_pi (``"v"``).
        max_steps: Step limit of an episode; truncated episodes are not averaged.
        start: Optional start state label (FiniteMDP only).
        model: The exact FiniteMDP behind an env (for the error curve), e.g.
            ``pl.problems.blackjack()`` for Gymnasium's Blackjack-v1.
        progress: Show a progress bar.
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).

    Returns:
        The :class:`LearnResult` (error against v_pi / q_pi where the model is known).
    """
    gen_policy, truth_policy = _fixed_policy(problem, policy, model, "mc_prediction")
    a = as_schedule(alpha, Schedule.inverse(), "alpha").check_range(0.0, 1.0, "alpha")
    return _run(
        "mc-prediction",
        problem,
        kind=AVERAGE,
        episodes=episodes,
        seed=seed,
        gamma=gamma,
        policy=gen_policy,
        policy_kind=FIXED_POLICY,
        epsilon=Schedule.constant(0.0),
        exploring_starts=False,
        eps_by_state=False,
        first_visit=bool(first_visit),
        alpha=a,
        weighted=False,
        target=None,
        truth_kind="prediction",
        truth_policy=truth_policy,
        error_on=error_on,
        checkpoints=checkpoints,
        max_steps=max_steps,
        start=start,
        progress=progress,
        model=model,
        score=score,
        params={"first_visit": bool(first_visit), "alpha": str(a)},
    )


def mc_control(
    problem: FiniteMDP | Any,
    *,
    episodes: int = 100_000,
    exploring_starts: bool = False,
    epsilon: Schedule | float | str | None = None,
    epsilon_by: Literal["episode", "state"] | None = None,
    alpha: Schedule | float | str | None = None,
    first_visit: bool = True,
    gamma: float | None = None,
    seed: Seed = None,
    checkpoints: int = 50,
    max_steps: int = 10_000,
    start: Hashable | None = None,
    model: FiniteMDP | None = None,
    progress: bool = False,
    score: bool = True,
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
        gamma: Discount rate (default: the problem's).
        seed: Seed or Generator; same seed, same result.
        checkpoints: About how many points of the error curve (log-spaced).
        max_steps: Step limit of an episode; truncated episodes are not used. On a
            deterministic task a greedy policy (exploring starts, small epsilon) can
            loop for ever: such episodes run to the limit and teach nothing (Monte
            Carlo needs episodes that end; Sutton & Barto section 5.3), so keep the
            limit small there and check ``result.truncated``.
        start: Optional start state label (FiniteMDP only, without exploring starts).
        model: The exact FiniteMDP behind an env (for the error curve).
        progress: Show a progress bar.
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).

    Returns:
        The :class:`LearnResult`; its error is measured against q*.
    """
    if epsilon_by is None:
        epsilon_by = "state" if epsilon is None else "episode"
    if epsilon_by not in ("episode", "state"):
        raise InvalidArgumentError(f"epsilon_by must be 'episode' or 'state'; got {epsilon_by!r}")
    if exploring_starts and epsilon is not None:
        raise InvalidArgumentError("exploring starts act greedily; do not give epsilon with them")
    eps = as_schedule(epsilon, Schedule.inverse(power=0.5), "epsilon")
    if epsilon_by == "episode":
        eps.check_range(0.0, 1.0, "epsilon")
    elif min(eps.a, eps.c) < 0:
        raise InvalidArgumentError(f"epsilon must be >= 0; schedule {eps} is negative")
    if exploring_starts:
        eps = Schedule.constant(0.0)
    a = as_schedule(alpha, Schedule.inverse(), "alpha").check_range(0.0, 1.0, "alpha")
    return _run(
        "mc-control",
        problem,
        kind=AVERAGE,
        episodes=episodes,
        seed=seed,
        gamma=gamma,
        policy=None,
        policy_kind=EPSILON_GREEDY,
        epsilon=eps,
        exploring_starts=bool(exploring_starts),
        eps_by_state=epsilon_by == "state",
        first_visit=bool(first_visit),
        alpha=a,
        weighted=False,
        target=None,
        truth_kind="control",
        truth_policy=None,
        error_on="q",
        checkpoints=checkpoints,
        max_steps=max_steps,
        start=start,
        progress=progress,
        model=model,
        score=score,
        params={
            "epsilon_by": epsilon_by,
            "exploring_starts": bool(exploring_starts),
            "epsilon": str(eps),
            "alpha": str(a),
            "first_visit": bool(first_visit),
        },
    )


def mc_off_policy(
    problem: FiniteMDP | Any,
    target: Policy | None = None,
    *,
    behavior: Policy | Callable[[Any], Any] | None = None,
    epsilon: Schedule | float | str | None = None,
    weighted: bool = False,
    episodes: int = 100_000,
    first_visit: bool = False,
    gamma: float | None = None,
    seed: Seed = None,
    checkpoints: int = 50,
    error_on: Literal["v", "q"] = "q",
    max_steps: int = 10_000,
    start: Hashable | None = None,
    model: FiniteMDP | None = None,
    progress: bool = False,
    score: bool = True,
) -> LearnResult:
    """Off-policy Monte Carlo by importance sampling, ordinary or weighted.

    Episodes come from a behaviour policy b; returns are reweighted by the importance
    sampling ratio rho_{t:T-1} = prod_k pi(A_k | S_k) / b(A_k | S_k). Ordinary IS
    averages rho G over all visits (unbiased, possibly huge variance); weighted IS
    divides by the sum of the ratios instead (biased, consistent, low variance).

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
        gamma: Discount rate (default: the problem's).
        seed: Seed or Generator; same seed, same result.
        checkpoints: About how many points of the error curve (log-spaced).
        error_on: For prediction: score Q (``"q"``) or V (``"v"``).
        max_steps: Step limit of an episode; truncated episodes are not used.
        start: Optional start state label (FiniteMDP only).
        model: The exact FiniteMDP behind an env (for the error curve).
        progress: Show a progress bar.
        score: Hold the estimate against the exact answer where the model is known
            (False skips the exact solve, for many short runs).

    Returns:
        The :class:`LearnResult`.
    """
    from policylab.mdp.policy import Policy

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
    gen_policy: Any = None
    if epsilon is not None:
        policy_kind = EPSILON_GREEDY
        eps = as_schedule(epsilon, Schedule.inverse(), "epsilon").check_range(0.0, 1.0, "epsilon")
        if eps.kind == CONSTANT and eps.a == 0.0:
            raise InvalidArgumentError("an epsilon-greedy behaviour needs epsilon > 0 (coverage)")
    else:
        gen_policy, _ = _fixed_policy(problem, behavior, model, "mc_off_policy behavior")
        if target is not None and isinstance(gen_policy, Policy):
            _check_coverage(target, gen_policy)
        elif target is None and isinstance(gen_policy, Policy):
            _check_soft(gen_policy)
    return _run(
        "mc-off-policy",
        problem,
        kind=IS_PREDICTION if target is not None else IS_CONTROL,
        episodes=episodes,
        seed=seed,
        gamma=gamma,
        policy=gen_policy,
        policy_kind=policy_kind,
        epsilon=eps,
        exploring_starts=False,
        eps_by_state=False,
        first_visit=bool(first_visit),
        alpha=Schedule.inverse(),
        weighted=bool(weighted),
        target=target,
        truth_kind="prediction" if target is not None else "control",
        truth_policy=target,
        error_on=error_on if target is not None else "q",
        checkpoints=checkpoints,
        max_steps=max_steps,
        start=start,
        progress=progress,
        model=model,
        score=score,
        params={
            "weighted": bool(weighted),
            "first_visit": bool(first_visit),
            "target": "greedy" if target is None else "given",
            "behavior": f"epsilon-greedy {eps}" if epsilon is not None else "fixed",
        },
    )


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
