"""Learning from experience on tables: Monte Carlo and the TD family.

Public names::

    import policylab as pl
    from policylab.tabular import Schedule, mc_control, mc_off_policy, mc_prediction
    res = mc_prediction(pl.problems.slippery_gridworld(), episodes=10_000, seed=0)
    res.q, res.v, res.policy, res.checkpoints, res.error_max, res.error_rms
    res = mc_control(mdp, episodes=100_000, seed=0)     # GLIE epsilon-greedy
    res = mc_off_policy(mdp, target=pi, weighted=True, seed=0)

Every learner takes ``problem`` = a :class:`~policylab.FiniteMDP` (the fast path:
episodes simulated and updates applied in compiled numba kernels) or a Gymnasium env
with discrete or hashable observations (the general path: a readable Python loop that
calls the *same* compiled update rule), and returns a :class:`LearnResult`.

Layout
------
``schedules``  :class:`Schedule` (constant, 1/n, exponential, linear; with floors) and
               ``schedule_value(params, n)``, the one function kernels evaluate.
``kernels``    the kernel conventions: per-run xoshiro RNG states from a seed
               (:func:`~policylab.tabular.kernels.rng_states`), sampling from the
               outcome table, epsilon-greedy action choice, :func:`generate_episode`,
               and ``env_reset``/``env_step``, through which a kernel reaches its
               environment (the model's arrays compiled, a ``GymStepper`` as Python).
``truth``      :class:`GroundTruth`: exact v_pi/q_pi or v*/q* (from policylab.planning)
               and the error of an estimate (max, RMS, share of optimal greedy actions).
``common``     ``run_seeds`` (several seeds at once, on threads; ``seed_study`` stacks
               its results), argument checks (``check_count``, ``check_fraction``,
               ``check_gamma``), checkpoints, the
               :class:`~policylab.tabular.common.Recorder` of the error curve, progress
               bars, and the general path: ``as_env``, ``env_name``, ``StateIndex``,
               ``GymStepper``.
``result``     :class:`LearnResult`, the one result type (``to_json()`` is the CLI's
               ``--json``).
``registry``   the algorithm registry ``policylab learn ALGO PROBLEM`` reads.
``mc``         Monte Carlo prediction, control and off-policy learning.
``td``         the TD family (chapters 6, 7, 8, 12) and ``seed_study``; its kernels,
               one source for both paths, are in ``td_kernels``.

How to add an algorithm (e.g. SARSA, in ``policylab/tabular/td.py``)
-------------------------------------------------------------------
1. Write the update rule once as an ``@numba.njit(cache=True)`` function, named after
   what it computes, with its equation in the docstring (for example
   ``sarsa_update(q, s, a, r, s2, a2, alpha, gamma, terminated)``: Q(S,A) <- Q(S,A) +
   alpha [R + gamma Q(S',A') - Q(S,A)]). Step sizes and epsilons come in as
   ``Schedule.params`` arrays and are read with ``schedule_value(params, n)``.
2. Write the fast path: an ``@njit(cache=True)`` kernel that runs episodes ``k0..k1-1``
   on the :class:`~policylab.tabular.kernels.KernelMDP` arrays with
   ``sample_start``/``sample_next``/``epsilon_greedy_action`` and the RNG state array
   from ``rng_states(seed)``, updating the tables in place and writing each episode's
   return into ``returns[k]``; it returns the number of steps taken.
3. Write the general path: the same loop in plain Python over ``env.reset``/``env.step``
   with a :class:`~policylab.tabular.common.StateIndex`, calling the same njit update
   rule and the same action choice with the same RNG state, so that on a deterministic
   MDP both paths agree exactly for the same seed (test it).
4. Write the public learner ``sarsa(problem, *, episodes, seed=None, gamma=None,
   alpha=..., epsilon=..., checkpoints=50, progress=False, ...) -> LearnResult``:
   ``GroundTruth.control(mdp)`` (or ``.prediction(mdp, pi)``) where the model is known,
   ``Recorder`` + ``progress_bar`` over ``Recorder.chunks()``, then ``LearnResult``.
5. Register it at the bottom of the module with
   ``register_algorithm("sarsa", sarsa, "one line", options=(Option("--alpha", "alpha",
   "schedule", "step size ..."), ...))`` and import the module here. The ``learn``
   command picks it up; nothing else to edit. Common options (``--episodes --seed
   --gamma --json --plot --checkpoints --max-steps --env``, and ``--policy`` for
   ``kind="prediction"``) are added by the command.
"""

from policylab.tabular.common import Recorder, StateIndex, checkpoint_episodes, run_seeds
from policylab.tabular.mc import mc_control, mc_off_policy, mc_prediction
from policylab.tabular.registry import (
    AlgorithmSpec,
    Option,
    algorithm,
    list_algorithms,
    register_algorithm,
)
from policylab.tabular.result import LearnResult
from policylab.tabular.schedules import Schedule, schedule_value
from policylab.tabular.td import (
    SeedRuns,
    double_q_learning,
    dyna_q,
    expected_sarsa,
    n_step_sarsa,
    n_step_td,
    q_learning,
    sarsa,
    sarsa_lambda,
    seed_study,
    td0,
    td_lambda,
)
from policylab.tabular.truth import GroundTruth, greedy_probs

__all__ = [
    "AlgorithmSpec",
    "GroundTruth",
    "LearnResult",
    "Option",
    "Recorder",
    "Schedule",
    "SeedRuns",
    "StateIndex",
    "algorithm",
    "checkpoint_episodes",
    "double_q_learning",
    "dyna_q",
    "expected_sarsa",
    "greedy_probs",
    "list_algorithms",
    "mc_control",
    "mc_off_policy",
    "mc_prediction",
    "n_step_sarsa",
    "n_step_td",
    "q_learning",
    "register_algorithm",
    "run_seeds",
    "sarsa",
    "sarsa_lambda",
    "schedule_value",
    "seed_study",
    "td0",
    "td_lambda",
]
