"""Learning from experience on tables: Monte Carlo and the TD family.

Public names::

    import policylab as pl
    from policylab import tabular
    res = tabular.q_learning(pl.problems.cliff_walking(), episodes=500, alpha=0.5, seed=0)
    res.q, res.v, res.policy, res.checkpoints, res.error_max, res.error_rms
    res = tabular.mc_control(mdp, episodes=100_000, seed=0)     # GLIE epsilon-greedy
    runs = tabular.seed_study("sarsa", mdp, seeds=200, episodes=500)   # one compiled call

Every learner takes ``problem`` = a :class:`~policylab.FiniteMDP` (the compiled path:
episodes simulated and updates applied in numba kernels) or a Gymnasium env with
discrete or hashable observations (the general path: the same episode loop and update
rules run as Python over ``env.reset``/``env.step``), and returns a :class:`LearnResult`.

The shared options, one convention for every learner (Monte Carlo and TD)
-------------------------------------------------------------------------
``problem`` first; ``policy`` second for prediction; then keywords: ``episodes``, the
algorithm's own options (``alpha`` and ``epsilon`` are each a number, a
:class:`Schedule` or a schedule string such as ``"1/n"`` or ``"exp:1,0.999,0.01"``),
and the options every learner shares, :class:`LearnOptions`: ``gamma`` (None: the
problem's), ``seed`` (int, Generator or None: same seed, same result), ``checkpoints``
(points of the error curve against the exact answer, log-spaced), ``max_steps`` (step
limit of an episode), ``model`` (the exact FiniteMDP behind an env, for the error
curve) and ``progress``. Each public function lists its own options in its signature
and takes the shared ones as ``**options: Unpack[LearnOptions]`` (editors and mypy show
their names and types).

Layout
------
``rules/``      the update rules, one small compiled function per equation, with its
                number and section of Sutton & Barto in the docstring (``rules.td``,
                ``rules.mc``).
``kernels``     the kernel conventions: per-run xoshiro RNG states (``rng_states``),
                sampling the model (a ``Model`` named tuple), ``choose_action`` (one
                action choice for every episode loop), ``generate_episode``.
``td_kernels``  the TD episodes, one function per family (TD(0), one-step control,
                n-step, lambda, Dyna-Q), each taking the same named tuples (``Model``,
                ``Tables``, ``Settings``), and the one loop over episodes that records
                them (``run_kernel``, compiled without reference counting);
                ``many_runs`` runs R seeds in one parallel (numba ``prange``) call.
                ``mc`` holds Monte Carlo's loop.
``driver``      the one driver of every built-in learner: an entry turns a call into
                a ``Plan`` (checked options, the problem, the exact answer, how to start
                one run or many); ``learn`` runs it for one seed (ground truth, seeding,
                chunks with progress, recording, :class:`LearnResult`), ``seed_study``
                for many seeds in one compiled call. ``LearnOptions``: the shared options.
``td``, ``mc``  the entries (``TD_ENTRIES``: one ``TDEntry`` per TD algorithm;
                ``MC_ENTRIES``: one ``MCEntry`` per Monte Carlo one, whose ``setup``
                maps its own options to the behaviour, update and ground truth) and the
                public functions, each one line: ``return learn_entry(name, locals())``.
``schedules``, ``truth``, ``common``, ``result``, ``registry``: schedules, the exact
                answer and the error, shared checks and the general path's
                ``StateIndex``/``GymStepper``, :class:`LearnResult`, and the registry
                that ``policylab learn ALGO PROBLEM`` and ``seed_study`` read.

How to add a learner
--------------------
1. Write each new update as one function in ``rules/td.py`` (``@register_jitable``,
   the equation and its section in the docstring), with a test against a hand value.
2. A new TD variant of an existing family: add its rule constant and branch to that
   family's episode in ``td_kernels`` (a new family: an episode function with the same
   six arguments, ``@register_jitable(_nrt=False)``, working memory in ``Tables``
   rather than allocated, returning (G_0, length, A_0); add it to ``run_kernel``).
3. Add a ``TDEntry`` to ``TD_ENTRIES`` in ``td.py`` (name, function name, family, the
   title and equation of its docstring, its own ``Option``s with annotation/default),
   then run ``python -m policylab.tabular._generate``: it writes the public function's
   signature and docstring; the driver, the registry, ``policylab learn`` and
   ``seed_study`` read the entry. Export the function here.
4. Any other learner function: ``register_algorithm("name", fn, "one line", options=
   (Option("--flag", "param", "float", "help"),), kind="control")``; ``policylab learn``
   lists it and passes its options (tests/tabular/test_registry.py does this).
"""

from policylab.tabular.common import Recorder, StateIndex, checkpoint_episodes, run_seeds
from policylab.tabular.driver import LearnOptions, SeedRuns, seed_study
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
    double_q_learning,
    dyna_q,
    expected_sarsa,
    n_step_sarsa,
    n_step_td,
    q_learning,
    sarsa,
    sarsa_lambda,
    td0,
    td_lambda,
)
from policylab.tabular.truth import GroundTruth, greedy_probs

__all__ = [
    "AlgorithmSpec",
    "GroundTruth",
    "LearnOptions",
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
