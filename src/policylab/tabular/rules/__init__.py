"""The tabular update rules, one small compiled function per equation of the book.

:mod:`~policylab.tabular.rules.td` holds the TD targets and updates (chapters 2, 6, 7),
:mod:`~policylab.tabular.rules.mc` the Monte Carlo averages and importance-sampling
updates (chapter 5). The episode loops (``td_kernels``, ``mc``) call them; tests and
readers find each equation here, with its number and section in the docstring.
"""

from policylab.tabular.rules.mc import episode_return, first_visit_flags, mc_episode_update
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

__all__ = [
    "double_q_target",
    "episode_return",
    "expected_sarsa_target",
    "first_visit_flags",
    "mc_episode_update",
    "n_step_return",
    "q_learning_target",
    "sarsa_target",
    "td_error",
    "td_target",
    "td_update",
]
