"""The TD family's update rules and episodes, each written once for both paths.

Every algorithm of Sutton & Barto chapters 6, 7, 8 and 12 is one episode function
below (``td0_episode``, ``one_step_control_episode``, ``n_step_episode``,
``lambda_episode``, ``dyna_q_episode``), in plain top-to-bottom Python, and one loop,
:func:`run_kernel`, runs the episodes of any family and records them:

* the **compiled path** calls ``run_kernel(family, None, model, ...)`` with ``model``
  the tuple of a FiniteMDP's arrays (:func:`model_tuple` of a
  :class:`~policylab.tabular.kernels.KernelMDP`): numba compiles the loop and the
  episodes, together with the sampling of the outcome table, without reference
  counting (see :func:`episode_loop`);
* the **general path** calls ``run_kernel.py_func(family, GymStepper(env, index), ...)``:
  the very same source, interpreted, over any Gymnasium env with discrete observations.

The environment is reached only through :func:`~policylab.tabular.kernels.env_reset`
and :func:`~policylab.tabular.kernels.env_step`; their compiled versions sample the
model with the shared kernel conventions
(:func:`~policylab.tabular.kernels.sample_start`,
:func:`~policylab.tabular.kernels.sample_next`: no random number for an outcome that
is certain), and the agent's choices use the shared
:func:`~policylab.tabular.kernels.epsilon_greedy_at` /
:func:`~policylab.tabular.kernels.sample_action` with the run's xoshiro state ``rng``.
So on a deterministic MDP both paths give bit-identical results for one seed.

Conventions of every episode: R_{t+1} follows A_t; an episode ends by ``terminated``
(no bootstrap) or by truncation (the env's time limit or ``max_steps``: bootstrap from
the last state). It updates its tables in place and returns (G_0 = sum_k gamma^k
R_{k+1}, its length, A_0 or -1); :func:`run_kernel` runs episodes ``k0 .. k1 - 1`` (so
that learners can record the error between chunks), writes those into
:class:`Episodes` and returns the number of environment steps taken. Step sizes are
read from a schedule at n = the number of updates of the entry so far (1/n is then the
sample average), exploration rates at n = the episode number.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit, prange
from numba.extending import register_jitable

from policylab.tabular.kernels import (
    Model,
    env_reset,
    env_step,
    episode_loop,
    epsilon_greedy_at,
    rand_below,
    sample_action,
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
    pass

__all__ = [
    "DOUBLE_Q",
    "DYNA",
    "EXPECTED_SARSA",
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
    "dyna_q_episode",
    "episode_loop",
    "expected_sarsa_target",
    "lambda_episode",
    "many_runs",
    "model_tuple",
    "n_step_episode",
    "n_step_return",
    "one_step_control_episode",
    "q_learning_target",
    "run_kernel",
    "sarsa_target",
    "td0_episode",
    "td_error",
    "td_target",
    "td_update",
]

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
@register_jitable(_nrt=False)
def td0_episode(
    env: Any, model: Model, tables: Tables, settings: Settings, rng: Any, epsilon: float
) -> tuple[float, int, int]:
    """One episode of tabular TD(0) prediction of v_pi (S&B section 6.1), in place on V.

    Each step: A ~ pi(. | S); take A, observe R, S'; V(S) <- V(S) + alpha [R + gamma
    V(S') - V(S)]; S <- S'.
    """
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    pi, counts = tables.pi, tables.counts[:, 0]
    v = tables.w[:, 0]
    s = env_reset(env, model, rng)
    g, disc, t = 0.0, 1.0, 0
    while True:
        a = sample_action(pi[s], rng)
        s2, r, terminated, truncated = env_step(env, model, s, a, rng)
        t, g, disc = t + 1, g + disc * r, disc * gamma
        counts[s] += 1
        alpha = schedule_value(alpha_params, float(counts[s]))
        v[s] = td_update(v[s], alpha, td_target(r, gamma, v[s2], terminated))
        if terminated or truncated or t >= max_steps:
            return g, t, -1
        s = s2


# ---------------------------------------------------------------------------- one-step control
@register_jitable(_nrt=False)
def one_step_control_episode(
    env: Any, model: Model, tables: Tables, settings: Settings, rng: Any, epsilon: float
) -> tuple[float, int, int]:
    """One episode of Sarsa, Q-learning, Expected Sarsa or Double Q-learning (S&B 6.4-6.7).

    ``rule`` :data:`SARSA`: A' ~ epsilon-greedy(Q(S', .)) is chosen *before* the
    update of Q(S, A) toward R + gamma Q(S', A'). :data:`Q_LEARNING` and
    :data:`EXPECTED_SARSA`: Q(S, A) moves toward R + gamma max_a Q(S', a) or toward
    R + gamma E_pi Q(S', .), and the next action is chosen after the update (the
    book's boxes). :data:`DOUBLE_Q`: a fair coin picks which of Q1, Q2 is updated
    (the other one values the argmax); behaviour is epsilon-greedy in Q1 + Q2.
    ``qb`` is the table the behaviour is epsilon-greedy in: ``q1`` itself, or for
    Double Q-learning a table kept equal to Q1 + Q2 entry by entry (one sum per update
    instead of one per step: the step loop then reads a single table, which keeps the
    compiled loop free of per-step array temporaries). A_0 is returned (Figure 6.5
    counts "left" in A).
    """
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    q1, q2, qb, counts, mask = tables.w, tables.q2, tables.qb, tables.counts, model.mask
    rule = settings.rule
    s = env_reset(env, model, rng)
    a = a0 = epsilon_greedy_at(qb, mask, s, epsilon, rng)
    g, disc, t = 0.0, 1.0, 0
    while True:
        s2, r, terminated, truncated = env_step(env, model, s, a, rng)
        t, g, disc = t + 1, g + disc * r, disc * gamma
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
            return g, t, a0
        if rule != SARSA:
            a2 = epsilon_greedy_at(qb, mask, s2, epsilon, rng)
        s, a = s2, a2


# ---------------------------------------------------------------------------- n-step
@register_jitable(_nrt=False)
def n_step_episode(
    env: Any, model: Model, tables: Tables, settings: Settings, rng: Any, epsilon: float
) -> tuple[float, int, int]:
    """One episode of n-step TD prediction (``control=False``) or n-step Sarsa (S&B 7.1, 7.2).

    ``w`` is the table learned: V as an (S, 1) column for prediction (actions from
    ``pi``), Q (S, A) for control (actions epsilon-greedy in Q). With tau = t - n + 1,

        G_{tau:tau+n} = sum_{i=tau+1}^{min(tau+n, T)} gamma^{i-tau-1} R_i
                        + gamma^n W(S_{tau+n}[, A_{tau+n}])   if tau + n < T

    and W(S_tau[, A_tau]) <- W + alpha [G - W]. A truncated episode bootstraps from its
    last state. With n = 1 this is exactly TD(0) or Sarsa. The last n + 1 states,
    actions and rewards are kept in the rings ``S_buf``, ``A_buf``, ``R_buf``.
    """
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    control, n, mask = settings.control, settings.n, model.mask
    pi, w, counts = tables.pi, tables.w, tables.counts
    S_buf, A_buf, R_buf = tables.ring_s, tables.ring_a, tables.ring_r
    m = n + 1
    s0 = env_reset(env, model, rng)
    S_buf[0] = s0
    a0 = -1
    if control:
        a0 = A_buf[0] = epsilon_greedy_at(w, mask, s0, epsilon, rng)
    T = np.iinfo(np.int64).max
    bootstrap_end = False
    g, disc, t = 0.0, 1.0, 0
    while True:
        if t < T:
            if not control:  # prediction: A_t ~ pi(. | S_t)
                A_buf[t % m] = sample_action(pi[S_buf[t % m]], rng)
            s2, r, terminated, truncated = env_step(env, model, S_buf[t % m], A_buf[t % m], rng)
            g, disc = g + disc * r, disc * gamma
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
            return g, T, a0
        t += 1


# ---------------------------------------------------------------------------- eligibility traces
@register_jitable(_nrt=False)
def lambda_episode(
    env: Any, model: Model, tables: Tables, settings: Settings, rng: Any, epsilon: float
) -> tuple[float, int, int]:
    """One episode of TD(lambda) (``control=False``) or Sarsa(lambda) (S&B 12.2, 12.7).

    Each step: delta = R + gamma W(S'[, A']) - W(S[, A]); the trace of the current
    entry is raised (accumulating: e <- e + 1; replacing: e <- 1); then for every entry
    W <- W + alpha delta e and e <- gamma lambda e. Traces are cleared at the start of
    each episode. With lambda = 0 this is exactly TD(0) or Sarsa. The step size is read
    at the current entry's update count.
    """
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    control, lam, trace, mask = settings.control, settings.lam, settings.trace, model.mask
    pi, w, counts, e = tables.pi, tables.w, tables.counts, tables.traces
    n_rows, n_cols = w.shape
    e[:, :] = 0.0
    s = env_reset(env, model, rng)
    a = a0 = epsilon_greedy_at(w, mask, s, epsilon, rng) if control else -1
    g, disc, t = 0.0, 1.0, 0
    while True:
        if not control:
            a = sample_action(pi[s], rng)
        s2, r, terminated, truncated = env_step(env, model, s, a, rng)
        t, g, disc = t + 1, g + disc * r, disc * gamma
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
            return g, t, a0
        s, a = s2, a2


# ---------------------------------------------------------------------------- Dyna-Q
@register_jitable(_nrt=False)
def dyna_q_episode(
    env: Any, model: Model, tables: Tables, settings: Settings, rng: Any, epsilon: float
) -> tuple[float, int, int]:
    """One episode of tabular Dyna-Q (S&B 8.2): Q-learning plus planning from a learned model.

    After each real step: the Q-learning update; Model(S, A) <- (R, S') (the last
    outcome seen: a deterministic model; ``model_next`` holds -1 for unseen pairs and
    -2 - S' for an outcome that terminated); then ``planning`` times: a pair (S, A)
    seen before, drawn uniformly; (R, S') <- Model(S, A); the same Q-learning update.
    ``seen[0]`` counts the pairs seen, ``seen[1:]`` lists them (kept across calls).
    With ``planning = 0`` this is exactly Q-learning.
    """
    gamma, alpha_params, max_steps = settings.gamma, settings.alpha, settings.max_steps
    n_planning, q, counts, mask = settings.planning, tables.w, tables.counts, model.mask
    model_next, model_reward, seen = tables.model_next, tables.model_reward, tables.seen
    n_actions = mask.shape[1]
    s = env_reset(env, model, rng)
    a = a0 = epsilon_greedy_at(q, mask, s, epsilon, rng)
    g, disc, t = 0.0, 1.0, 0
    while True:
        s2, r, terminated, truncated = env_step(env, model, s, a, rng)
        t, g, disc = t + 1, g + disc * r, disc * gamma
        counts[s, a] += 1
        alpha = schedule_value(alpha_params, float(counts[s, a]))
        q[s, a] = td_update(q[s, a], alpha, q_learning_target(r, gamma, q, mask, s2, terminated))
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
            return g, t, a0
        a = epsilon_greedy_at(q, mask, s2, epsilon, rng)
        s = s2


# ---------------------------------------------------------------------------- the episode loop
#: Families of :func:`run_kernel`: which episode a learner runs.
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
    """Run episodes k0 .. k1 - 1 of ``family``'s episode; return the environment steps.

    The one loop over episodes of every family: episode k explores at the rate of the
    schedule at k + 1; its return G_0 = sum_t gamma^t R_{t+1} goes into
    ``out.returns[k]``, its length into ``out.lengths[k]``, its first action A_0 into
    ``out.first_actions[k]`` (-1 where the family draws it inside the episode).
    """
    steps = 0
    for k in range(k0, k1):
        epsilon = schedule_value(settings.epsilon, k + 1.0)
        if family == TD0:
            g, t, a0 = td0_episode(env, model, tables, settings, rng, epsilon)
        elif family == ONE_STEP:
            g, t, a0 = one_step_control_episode(env, model, tables, settings, rng, epsilon)
        elif family == N_STEP:
            g, t, a0 = n_step_episode(env, model, tables, settings, rng, epsilon)
        elif family == LAMBDA:
            g, t, a0 = lambda_episode(env, model, tables, settings, rng, epsilon)
        else:
            g, t, a0 = dyna_q_episode(env, model, tables, settings, rng, epsilon)
        out.returns[k] = g
        out.lengths[k] = t
        out.first_actions[k] = a0
        steps += t
    return steps


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
        # k0 as an int64, not the literal 0: a literal argument would compile (and cache)
        # a second copy of the whole episode loop, beside the one the single runs use
        k0 = int(0)  # noqa: UP018, RUF046
        steps[r] = run_kernel(family, None, model, run_tables, settings, run_out, rng, k0, episodes)
        rngs[r] = rng
    return steps
