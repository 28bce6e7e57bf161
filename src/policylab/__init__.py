"""policylab: reinforcement learning from finite MDPs to deep RL.

The public names of the core live here::

    import policylab as pl
    mdp = pl.problems.recycling_robot()
    pi = pl.Policy.deterministic(mdp, {"low": "recharge", "high": "search"})
"""

# First: policylab's compiled kernels are cached in a folder keyed by their source.
from policylab import _numba_cache as _numba_cache
from policylab import problems, stats
from policylab.envs import Episode, MDPEnv, register_envs, rollout
from policylab.exceptions import (
    CheckpointError,
    InvalidActionError,
    InvalidArgumentError,
    InvalidMDPError,
    InvalidPolicyError,
    NotConvergedWarning,
    PolicylabError,
    ShapeError,
    UnknownLabelError,
    UnknownProblemError,
)
from policylab.mdp import FiniteMDP, GridLayout, Policy, discounted_return, grid_mdp, returns_to_go
from policylab.planning import (
    PlanningResult,
    action_values,
    backward_induction,
    compare_policies,
    evaluate_policy,
    greedy_policy,
    linear_programming,
    modified_policy_iteration,
    optimal_actions,
    policy_iteration,
    relative_value_iteration,
    value_iteration,
)

__version__ = "0.1.0"

register_envs()

__all__ = [
    "CheckpointError",
    "Episode",
    "FiniteMDP",
    "GridLayout",
    "InvalidActionError",
    "InvalidArgumentError",
    "InvalidMDPError",
    "InvalidPolicyError",
    "MDPEnv",
    "NotConvergedWarning",
    "PlanningResult",
    "Policy",
    "PolicylabError",
    "ShapeError",
    "UnknownLabelError",
    "UnknownProblemError",
    "__version__",
    "action_values",
    "backward_induction",
    "compare_policies",
    "discounted_return",
    "evaluate_policy",
    "greedy_policy",
    "grid_mdp",
    "linear_programming",
    "modified_policy_iteration",
    "optimal_actions",
    "policy_iteration",
    "problems",
    "register_envs",
    "relative_value_iteration",
    "returns_to_go",
    "rollout",
    "stats",
    "value_iteration",
]


def __getattr__(name: str) -> object:
    """Load ``policylab.deep`` (and so torch) only when first used: ``pl.deep.PPO``."""
    if name == "deep":
        import importlib

        return importlib.import_module("policylab.deep")
    raise AttributeError(f"module 'policylab' has no attribute {name!r}")
