"""The problem layer: finite MDPs, policies, returns and grid builders."""

from policylab.mdp.finite import PROB_TOL, FiniteMDP, Outcome
from policylab.mdp.grid import MOVES, Cell, GridLayout, grid_mdp
from policylab.mdp.policy import POLICY_TOL, Policy
from policylab.mdp.postdecision import PostDecisionKernel, PostDecisionMDP
from policylab.mdp.returns import discounted_return, returns_to_go

__all__ = [
    "MOVES",
    "POLICY_TOL",
    "PROB_TOL",
    "Cell",
    "FiniteMDP",
    "GridLayout",
    "Outcome",
    "Policy",
    "PostDecisionKernel",
    "PostDecisionMDP",
    "discounted_return",
    "grid_mdp",
    "returns_to_go",
]
