"""Exact planning on a finite MDP (notes section 5; Sutton & Barto chapters 3-4).

One function per Bellman equation (:mod:`policylab.planning.bellman`), policy
evaluation (exact and iterative), comparison of policies, and the solvers of the
Bellman optimality equation: value iteration (synchronous and Gauss-Seidel), policy
iteration, modified policy iteration, linear programming, finite-horizon backward
induction and relative value iteration (average reward). Every solver returns a
:class:`PlanningResult`; :func:`solve` runs one by name or picks one (``"auto"``).
"""

from policylab.planning.auto import METHODS, choose_method, solve
from policylab.planning.bellman import (
    DEFAULT_TIE_TOL,
    action_values,
    bellman_expectation_backup,
    bellman_optimality_backup,
    greedy_actions,
    greedy_policy,
    optimal_actions,
    policy_reward,
    policy_transition_matrix,
    proper_actions,
    state_values,
)
from policylab.planning.compare import compare_policies
from policylab.planning.control import (
    modified_policy_iteration,
    policy_iteration,
    proper_policy,
    value_iteration,
)
from policylab.planning.evaluation import evaluate_policy, solve_policy_system
from policylab.planning.result import PlanningResult
from policylab.planning.special import (
    backward_induction,
    linear_programming,
    relative_value_iteration,
)

__all__ = [
    "DEFAULT_TIE_TOL",
    "METHODS",
    "PlanningResult",
    "action_values",
    "backward_induction",
    "bellman_expectation_backup",
    "bellman_optimality_backup",
    "choose_method",
    "compare_policies",
    "evaluate_policy",
    "greedy_actions",
    "greedy_policy",
    "linear_programming",
    "modified_policy_iteration",
    "optimal_actions",
    "policy_iteration",
    "policy_reward",
    "policy_transition_matrix",
    "proper_actions",
    "proper_policy",
    "relative_value_iteration",
    "solve",
    "solve_policy_system",
    "state_values",
    "value_iteration",
]
