"""policylab: reinforcement learning from finite MDPs to deep RL.

The public names of the core live here::

    import policylab as pl
    mdp = pl.problems.recycling_robot()
    pi = pl.Policy.deterministic(mdp, {"low": "recharge", "high": "search"})
"""

from policylab import problems
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
    "Policy",
    "PolicylabError",
    "ShapeError",
    "UnknownLabelError",
    "UnknownProblemError",
    "__version__",
    "discounted_return",
    "grid_mdp",
    "problems",
    "register_envs",
    "returns_to_go",
    "rollout",
]


def __getattr__(name: str) -> object:
    """Load ``policylab.deep`` (and so torch) only when first used: ``pl.deep.PPO``."""
    if name == "deep":
        import importlib

        return importlib.import_module("policylab.deep")
    raise AttributeError(f"module 'policylab' has no attribute {name!r}")
