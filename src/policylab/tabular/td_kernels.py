"""The TD family's update rules and episode loops, each written once for both paths.

Every algorithm of Sutton & Barto chapters 6, 7, 8 and 12 is one function below, in
plain top-to-bottom Python that numba compiles:

* the **compiled path** calls ``kernel(model, ...)`` with ``model`` the tuple of a
  FiniteMDP's arrays (:func:`model_tuple` of a
  :class:`~policylab.tabular.kernels.KernelMDP`): numba compiles the loop together with
  the sampling of the outcome table;
* the **general path** calls ``kernel.py_func(GymStepper(env, index), ...)``: the very
  same source, interpreted, over any Gymnasium env with discrete observations.

The environment is reached only through :func:`env_reset` and :func:`env_step`; their
compiled versions sample the model with the shared kernel conventions
(:func:`~policylab.tabular.kernels.sample_start`,
:func:`~policylab.tabular.kernels.sample_next`: no random number for an outcome that
is certain), and the agent's choices use the shared
:func:`~policylab.tabular.kernels.epsilon_greedy_at` /
:func:`~policylab.tabular.kernels.sample_action` with the run's xoshiro state ``rng``.
So on a deterministic MDP both paths give bit-identical results for one seed.

Conventions of every kernel: R_{t+1} follows A_t; an episode ends by ``terminated``
(no bootstrap) or by truncation (the env's time limit or ``max_steps``: bootstrap from
the last state). A kernel runs episodes ``k0 .. k1 - 1`` (so that learners can record
the error between chunks), updates its tables in place, writes each episode's return
G_0 = sum_k gamma^k R_{k+1} into ``returns[k]`` and its length into ``lengths[k]``,
and returns the number of environment steps taken. Step sizes are read from a
schedule at n = the number of updates of the entry so far (1/n is then the sample
average), exploration rates at n = the episode number.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar

import numpy as np
from numba import njit, prange

from policylab.tabular.kernels import (
    Model,
    env_reset,
    env_step,
    epsilon_greedy_at,
    rand_below,
    sample_action,
    sample_next,
)
from policylab.tabular.rules.td import (
    double_q_target,
    expected_sarsa_target,
    n_step_return,
    q_learning_target,
    sarsa_target,
    td_error,
    td_target,
    td_update,
)
from policylab.tabular.schedules import schedule_value

if TYPE_CHECKING:
    from numba.core.dispatcher import Dispatcher

__all__ = [
    "DOUBLE_Q",
    "DYNA",
    "EXPECTED_SARSA",
    "KERNELS",
    "LAMBDA",
    "N_STEP",
    "ONE_STEP",
    "Q_LEARNING",
    "SARSA",
    "TD0",
    "TRACE_ACCUMULATING",
    "TRACE_REPLACING",
    "Episodes",
    "Model",
    "Settings",
    "Tables",
    "double_q_target",
    "dyna_q_kernel",
    "episode_loop",
    "expected_sarsa_target",
    "lambda_kernel",
    "many_runs",
    "model_tuple",
    "n_step_kernel",
    "n_step_return",
    "one_step_control_kernel",
    "q_learning_target",
    "run_kernel",
    "sarsa_target",
    "td0_kernel",
    "td_error",
    "td_target",
    "td_update",
]

_F = TypeVar("_F", bound=Callable[..., object])


def episode_loop(fn: _F) -> Dispatcher[_F]:
    """Compile an episode loop: ``njit(cache=True, nogil=True)`` without reference counting.

    numba counts the references to every array a compiled function holds; each
    array a loop hands to an inlined helper (``epsilon_greedy_at``, ``sample_next``, the
    RNG draws) then costs an atomic increment and decrement of its count at every step,
    which numba cannot prune across the helpers' branches: they were more than half the
    time of a Q-learning step. Compiled without them (numba's ``_nrt=False``), a loop
    allocates nothing (its working memory comes in :class:`Tables`) and only borrows
    the arrays its caller keeps alive.
    """
    no_reference_counting: dict[str, Any] = {"_nrt": False}  # not in numba's stubs
    loop: Dispatcher[_F] = njit(fn, cache=True, nogil=True, **no_reference_counting)
    return loop


#: Rules of :func:`one_step_control_kernel`.
SARSA, Q_LEARNING, EXPECTED_SARSA, DOUBLE_Q = 0, 1, 2, 3
#: Eligibility-trace kinds of :func:`lambda_kernel`.
TRACE_ACCUMULATING, TRACE_REPLACING = 0, 1


# ---------------------------------------------------------------------------- arguments
class Settings(NamedTuple):
    """The fixed settings of one run: discount, schedules, step limit, the algorithm's own.

    ``alpha`` and ``epsilon`` are :attr:`~policylab.tabular.Schedule.params` arrays;
    ``rule`` one of :data:`SARSA`, :data:`Q_LEARNING`, :data:`EXPECTED_SARSA`,
    :data:`DOUBLE_Q` (one-step control); ``n`` the steps of an n-step return; ``lam``
    and ``trace`` (:data:`TRACE_ACCUMULATING`, :data:`TRACE_REPLACING`) of a lambda
    method; ``planning`` the Dyna-Q planning updates per step; ``control`` whether the
    table is Q (S, A) rather than V (S, 1).
    """

    gamma: float
    alpha: Any
    epsilon: Any
    max_steps: int
    rule: int
    n: int
    lam: float
    trace: int
    planning: int
    control: bool


class Tables(NamedTuple):
    """What one run learns and keeps between calls, updated in place.

    ``w``: V (S, 1) or Q (S, A) (Q1 for Double Q); ``q2``: Q2 of Double Q; ``qb``: the
    table the behaviour is epsilon-greedy in (``w`` itself, or Q1 + Q2 kept up to date);
    ``counts``: updates of each entry (the step size's n); ``pi``: the (S, A) policy
    evaluated (prediction); ``model_next``, ``model_reward``, ``seen``: Dyna-Q's learned
    model; ``traces``: the eligibility traces e of a lambda method (the shape of ``w``);
    ``ring_s``, ``ring_a``, ``ring_r``: the n-step methods' last n + 1 states, actions and
    rewards. Tables a family does not use are empty.
    """

    w: Any
    q2: Any
    qb: Any
    counts: Any
    pi: Any
    model_next: Any
    model_reward: Any
    seen: Any
    traces: Any
    ring_s: Any
    ring_a: Any
    ring_r: Any


class Episodes(NamedTuple):
    """Per-episode records a kernel writes: return G_0, length and first action A_0."""

    returns: Any
    lengths: Any
    first_actions: Any


def model_tuple(km: Any | None, mask: Any = None) -> Model:
    """The :class:`Model` of a :class:`~policylab.tabular.kernels.KernelMDP`.

    With None (the general path, which steps a Gymnasium env instead) empty arrays of
    the same types, and ``mask`` (default: an empty (0, 0) mask) as A(s).
    """
    if km is None:
        return Model(
            np.zeros(1, dtype=np.int64),
            np.zeros(0, dtype=np.int32),
            np.zeros(0),
            np.zeros(0),
            np.zeros(1, dtype=np.bool_),
            np.zeros(1),
            np.zeros((0, 0), dtype=np.bool_) if mask is None else mask,
        )
    return Model(
        km.indptr,
        km.next_states,
        km.cdf,
        km.rewards,
        km.terminal,
        km.initial,
        km.mask if mask is None else mask,
    )


# ---------------------------------------------------------------------------- TD(0)
@episode_loop
def td0_kernel(
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """Tabular TD(0) prediction of v_pi (S&B section 6.1), in place on ``v``.

    Each step: A ~ pi(. | S); take A, observe R, S'; V(S) <- V(S) + alpha [R + gamma
    V(S') - V(S)]; S <- S'.
    """
    indptr, next_states, cdf, rewards, terminal, initial, mask = model
    returns, lengths = out.returns, out.lengths
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    pi, counts = tables.pi, tables.counts[:, 0]
    v = tables.w[:, 0]
    n_actions = mask.shape[1]
    steps = 0
    for k in range(k0, k1):
        s = env_reset(env, initial, rng)
        g, disc, t = 0.0, 1.0, 0
        while True:
            a = sample_action(pi[s], rng)
            s2, r, terminated, truncated = env_step(
                env, s, a, rng, indptr, next_states, cdf, rewards, terminal, n_actions
            )
            t += 1
            g += disc * r
            disc *= gamma
            counts[s] += 1
            alpha = schedule_value(alpha_params, float(counts[s]))
            v[s] = td_update(v[s], alpha, td_target(r, gamma, v[s2], terminated))
            if terminated or truncated or t >= max_steps:
                break
            s = s2
        returns[k] = g
        lengths[k] = t
        steps += t
    return steps


# ---------------------------------------------------------------------------- one-step control
@episode_loop
def one_step_control_kernel(
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """Sarsa, Q-learning, Expected Sarsa or Double Q-learning (S&B 6.4-6.7), in place.

    ``rule`` :data:`SARSA`: A' ~ epsilon-greedy(Q(S', .)) is chosen *before* the
    update of Q(S, A) toward R + gamma Q(S', A'). :data:`Q_LEARNING` and
    :data:`EXPECTED_SARSA`: Q(S, A) moves toward R + gamma max_a Q(S', a) or toward
    R + gamma E_pi Q(S', .), and the next action is chosen after the update (the
    book's boxes). :data:`DOUBLE_Q`: a fair coin picks which of Q1, Q2 is updated
    (the other one values the argmax); behaviour is epsilon-greedy in Q1 + Q2.
    ``qb`` is the table the behaviour is epsilon-greedy in: ``q1`` itself, or for
    Double Q-learning a table kept equal to Q1 + Q2 entry by entry (one sum per update
    instead of one per step: the step loop then reads a single table, which keeps the
    compiled loop free of per-step array temporaries).
    ``first_actions[k]`` receives A_0 of episode k (Figure 6.5 counts "left" in A).

    The step is :func:`~policylab.tabular.kernels.env_step` written out in the loop
    (numba prunes the ``env is None`` branch): the call, with its six array arguments,
    cost this hottest loop a third of its speed.
    """
    indptr, next_states, cdf, rewards, terminal, initial, mask = model
    returns, lengths = out.returns, out.lengths
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    epsilon_params, rule, first_actions = settings.epsilon, settings.rule, out.first_actions
    q1, q2, qb, counts = tables.w, tables.q2, tables.qb, tables.counts
    n_actions = mask.shape[1]
    steps = 0
    for k in range(k0, k1):
        epsilon = schedule_value(epsilon_params, k + 1.0)
        s = env_reset(env, initial, rng)
        a = epsilon_greedy_at(qb, mask, s, epsilon, rng)
        first_actions[k] = a
        g, disc, t = 0.0, 1.0, 0
        while True:
            if env is None:  # compiled path: one outcome of row s * A + a of the model
                o = sample_next(indptr, cdf, s * n_actions + a, rng)
                s2, r, terminated, truncated = (
                    next_states[o],
                    rewards[o],
                    terminal[next_states[o]],
                    False,
                )
            else:  # general path: the Gymnasium env (what env_step does, written out for speed)
                s2, r, terminated, truncated = env.step(a)
            t += 1
            g += disc * r
            disc *= gamma
            counts[s, a] += 1
            alpha = schedule_value(alpha_params, float(counts[s, a]))
            a2 = 0
            if rule == SARSA:
                q_next = 0.0
                if not terminated:
                    a2 = epsilon_greedy_at(q1, mask, s2, epsilon, rng)
                    q_next = q1[s2, a2]
                q1[s, a] = td_update(q1[s, a], alpha, sarsa_target(r, gamma, q_next, terminated))
            elif rule == Q_LEARNING:
                target = q_learning_target(r, gamma, q1, mask, s2, terminated)
                q1[s, a] = td_update(q1[s, a], alpha, target)
            elif rule == EXPECTED_SARSA:
                target = expected_sarsa_target(r, gamma, q1[s2], mask[s2], epsilon, terminated)
                q1[s, a] = td_update(q1[s, a], alpha, target)
            elif rule == DOUBLE_Q:
                if rand_below(rng, 2) == 0:  # the coin: update Q1 (else Q2)
                    target = double_q_target(r, gamma, q1[s2], q2[s2], mask[s2], terminated)
                    q1[s, a] = td_update(q1[s, a], alpha, target)
                else:
                    target = double_q_target(r, gamma, q2[s2], q1[s2], mask[s2], terminated)
                    q2[s, a] = td_update(q2[s, a], alpha, target)
                qb[s, a] = q1[s, a] + q2[s, a]
            if terminated or truncated or t >= max_steps:
                break
            if rule != SARSA:
                a2 = epsilon_greedy_at(qb, mask, s2, epsilon, rng)
            s, a = s2, a2
        returns[k] = g
        lengths[k] = t
        steps += t
    return steps


# ---------------------------------------------------------------------------- n-step
@episode_loop
def n_step_kernel(
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """n-step TD prediction (``control=False``) or n-step Sarsa (S&B 7.1, 7.2), in place.

    ``w`` is the table learned: V as an (S, 1) column for prediction (actions from
    ``pi``), Q (S, A) for control (actions epsilon-greedy in Q). With tau = t - n + 1,

        G_{tau:tau+n} = sum_{i=tau+1}^{min(tau+n, T)} gamma^{i-tau-1} R_i
                        + gamma^n W(S_{tau+n}[, A_{tau+n}])   if tau + n < T

    and W(S_tau[, A_tau]) <- W + alpha [G - W]. A truncated episode bootstraps from its
    last state. With n = 1 this is exactly TD(0) or Sarsa.
    """
    indptr, next_states, cdf, rewards, terminal, initial, mask = model
    returns, lengths = out.returns, out.lengths
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    epsilon_params, control, n = settings.epsilon, settings.control, settings.n
    pi, w, counts = tables.pi, tables.w, tables.counts
    n_actions = mask.shape[1]
    S_buf, A_buf, R_buf = tables.ring_s, tables.ring_a, tables.ring_r
    m = n + 1
    big = np.iinfo(np.int64).max
    steps = 0
    for k in range(k0, k1):
        epsilon = schedule_value(epsilon_params, k + 1.0)
        s0 = env_reset(env, initial, rng)
        S_buf[0] = s0
        if control:
            A_buf[0] = epsilon_greedy_at(w, mask, s0, epsilon, rng)
        T = big
        bootstrap_end = False
        g, disc, t = 0.0, 1.0, 0
        while True:
            if t < T:
                if not control:  # prediction: A_t ~ pi(. | S_t)
                    A_buf[t % m] = sample_action(pi[S_buf[t % m]], rng)
                s2, r, terminated, truncated = env_step(
                    env,
                    S_buf[t % m],
                    A_buf[t % m],
                    rng,
                    indptr,
                    next_states,
                    cdf,
                    rewards,
                    terminal,
                    n_actions,
                )
                g += disc * r
                disc *= gamma
                R_buf[(t + 1) % m] = r
                S_buf[(t + 1) % m] = s2
                if terminated or truncated or t + 1 >= max_steps:
                    T = t + 1
                    bootstrap_end = not terminated
                if control and not terminated:
                    A_buf[(t + 1) % m] = epsilon_greedy_at(w, mask, s2, epsilon, rng)
            tau = t - n + 1
            if tau < 0 and t >= T - 1:  # the episode ended before n steps: skip idle t
                t, tau = n - 1, 0
            if tau >= 0:
                end = min(tau + n, T)
                G, p = n_step_return(R_buf, tau, end, gamma)
                if end < T or bootstrap_end:
                    G += p * w[S_buf[end % m], A_buf[end % m] if control else 0]
                s_tau = S_buf[tau % m]
                c_tau = A_buf[tau % m] if control else 0
                counts[s_tau, c_tau] += 1
                alpha = schedule_value(alpha_params, float(counts[s_tau, c_tau]))
                w[s_tau, c_tau] = td_update(w[s_tau, c_tau], alpha, G)
            if tau == T - 1:
                break
            t += 1
        returns[k] = g
        lengths[k] = T
        steps += T
    return steps


# ---------------------------------------------------------------------------- eligibility traces
@episode_loop
def lambda_kernel(
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """Tabular TD(lambda) (``control=False``) or Sarsa(lambda) (S&B 12.2, 12.7), in place.

    Each step: delta = R + gamma W(S'[, A']) - W(S[, A]); the trace of the current
    entry is raised (accumulating: e <- e + 1; replacing: e <- 1); then for every entry
    W <- W + alpha delta e and e <- gamma lambda e. Traces are cleared at the start of
    each episode. With lambda = 0 this is exactly TD(0) or Sarsa. The step size is read
    at the current entry's update count.
    """
    indptr, next_states, cdf, rewards, terminal, initial, mask = model
    returns, lengths = out.returns, out.lengths
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    epsilon_params, control = settings.epsilon, settings.control
    lam, trace = settings.lam, settings.trace
    pi, w, counts = tables.pi, tables.w, tables.counts
    n_actions = mask.shape[1]
    e = tables.traces
    n_rows, n_cols = w.shape
    steps = 0
    for k in range(k0, k1):
        epsilon = schedule_value(epsilon_params, k + 1.0)
        e[:, :] = 0.0
        s = env_reset(env, initial, rng)
        a = epsilon_greedy_at(w, mask, s, epsilon, rng) if control else 0
        g, disc, t = 0.0, 1.0, 0
        while True:
            if not control:
                a = sample_action(pi[s], rng)
            s2, r, terminated, truncated = env_step(
                env, s, a, rng, indptr, next_states, cdf, rewards, terminal, n_actions
            )
            t += 1
            g += disc * r
            disc *= gamma
            c = a if control else 0
            a2 = 0
            w_next = 0.0
            if not terminated:
                if control:
                    a2 = epsilon_greedy_at(w, mask, s2, epsilon, rng)
                    w_next = w[s2, a2]
                else:
                    w_next = w[s2, 0]
            delta = td_error(r, gamma, w_next, w[s, c], terminated)
            if trace == TRACE_REPLACING:
                e[s, c] = 1.0
            else:
                e[s, c] += 1.0
            counts[s, c] += 1
            alpha = schedule_value(alpha_params, float(counts[s, c]))
            for i in range(n_rows):
                for j in range(n_cols):
                    if e[i, j] != 0.0:
                        w[i, j] += alpha * delta * e[i, j]
                        e[i, j] *= gamma * lam
            if terminated or truncated or t >= max_steps:
                break
            s, a = s2, a2
        returns[k] = g
        lengths[k] = t
        steps += t
    return steps


# ---------------------------------------------------------------------------- Dyna-Q
@episode_loop
def dyna_q_kernel(
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """Tabular Dyna-Q (S&B 8.2): Q-learning plus ``n_planning`` updates from a learned model.

    After each real step: the Q-learning update; Model(S, A) <- (R, S') (the last
    outcome seen: a deterministic model; ``model_next`` holds -1 for unseen pairs and
    -2 - S' for an outcome that terminated); then ``n_planning`` times: a pair (S, A)
    seen before, drawn uniformly; (R, S') <- Model(S, A); the same Q-learning update.
    ``seen[0]`` counts the pairs seen, ``seen[1:]`` lists them (kept across calls).
    With ``n_planning = 0`` this is exactly Q-learning.
    """
    indptr, next_states, cdf, rewards, terminal, initial, mask = model
    returns, lengths = out.returns, out.lengths
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    epsilon_params, n_planning = settings.epsilon, settings.planning
    q, counts = tables.w, tables.counts
    model_next, model_reward, seen = tables.model_next, tables.model_reward, tables.seen
    n_actions = mask.shape[1]
    steps = 0
    for k in range(k0, k1):
        epsilon = schedule_value(epsilon_params, k + 1.0)
        s = env_reset(env, initial, rng)
        a = epsilon_greedy_at(q, mask, s, epsilon, rng)
        g, disc, t = 0.0, 1.0, 0
        while True:
            s2, r, terminated, truncated = env_step(
                env, s, a, rng, indptr, next_states, cdf, rewards, terminal, n_actions
            )
            t += 1
            g += disc * r
            disc *= gamma
            counts[s, a] += 1
            alpha = schedule_value(alpha_params, float(counts[s, a]))
            q[s, a] = td_update(
                q[s, a], alpha, q_learning_target(r, gamma, q, mask, s2, terminated)
            )
            if model_next[s, a] == -1:
                seen[0] += 1
                seen[seen[0]] = s * n_actions + a
            model_next[s, a] = -2 - s2 if terminated else s2
            model_reward[s, a] = r
            for _ in range(n_planning):
                pick = seen[1 + rand_below(rng, seen[0])]
                ps, pa = pick // n_actions, pick % n_actions
                pn = model_next[ps, pa]
                p_term = pn <= -2
                if p_term:
                    pn = -2 - pn
                target = q_learning_target(model_reward[ps, pa], gamma, q, mask, pn, p_term)
                counts[ps, pa] += 1
                p_alpha = schedule_value(alpha_params, float(counts[ps, pa]))
                q[ps, pa] = td_update(q[ps, pa], p_alpha, target)
            if terminated or truncated or t >= max_steps:
                break
            a = epsilon_greedy_at(q, mask, s2, epsilon, rng)
            s = s2
        returns[k] = g
        lengths[k] = t
        steps += t
    return steps


# ---------------------------------------------------------------------------- one call, many runs
#: Families of :func:`run_kernel`: which episode loop a learner runs.
TD0, ONE_STEP, N_STEP, LAMBDA, DYNA = 0, 1, 2, 3, 4


@episode_loop
def run_kernel(
    family: int,
    env: Any,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rng: Any,
    k0: int,
    k1: int,
) -> int:
    """Run episodes k0 .. k1 - 1 of the episode loop of ``family``; return the steps."""
    if family == TD0:
        return td0_kernel(env, model, tables, settings, out, rng, k0, k1)
    if family == ONE_STEP:
        return one_step_control_kernel(env, model, tables, settings, out, rng, k0, k1)
    if family == N_STEP:
        return n_step_kernel(env, model, tables, settings, out, rng, k0, k1)
    if family == LAMBDA:
        return lambda_kernel(env, model, tables, settings, out, rng, k0, k1)
    return dyna_q_kernel(env, model, tables, settings, out, rng, k0, k1)


#: The episode loop of each family (their ``py_func`` is the general path).
KERNELS = {
    TD0: td0_kernel,
    ONE_STEP: one_step_control_kernel,
    N_STEP: n_step_kernel,
    LAMBDA: lambda_kernel,
    DYNA: dyna_q_kernel,
}


@njit(cache=True, parallel=True)
def many_runs(
    family: int,
    model: Model,
    tables: Tables,
    settings: Settings,
    out: Episodes,
    rngs: Any,
    episodes: int,
) -> Any:
    """Run R independent runs of ``episodes`` episodes each, in parallel over runs.

    ``tables`` and ``out`` hold every run's arrays with a leading run axis (R, ...),
    except ``tables.pi``, the one policy every run evaluates; ``rngs`` (R, 4) is every
    run's own xoshiro state. Run r touches only its own slices and its own RNG stream,
    so its numbers are those of the run alone, whatever the number of threads (numba's
    ``prange``; set with ``numba.set_num_threads``). Returns the steps of each run.

    What a run writes at every step and is smaller than a cache line (its RNG state,
    the n-step rings) is worked on in a copy of its own, so that two threads running
    neighbouring runs never write to the same cache line (false sharing).
    """
    n_runs = rngs.shape[0]
    steps = np.zeros(n_runs, dtype=np.int64)
    for r in prange(n_runs):
        rng = rngs[r].copy()
        run_tables = Tables(
            tables.w[r],
            tables.q2[r],
            tables.qb[r],
            tables.counts[r],
            tables.pi,
            tables.model_next[r],
            tables.model_reward[r],
            tables.seen[r],
            tables.traces[r],
            tables.ring_s[r].copy(),
            tables.ring_a[r].copy(),
            tables.ring_r[r].copy(),
        )
        run_out = Episodes(out.returns[r], out.lengths[r], out.first_actions[r])
        steps[r] = run_kernel(family, None, model, run_tables, settings, run_out, rng, 0, episodes)
        rngs[r] = rng
    return steps
