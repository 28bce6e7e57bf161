"""Built-in problems: the notes' examples, textbook classics and generators.

Each problem is a function returning a :class:`~policylab.FiniteMDP`; every one is also
registered by name for the command line and as a Gymnasium id.
"""

from policylab.problems.applications import forest_management, inventory_management
from policylab.problems.blackjack import BLACKJACK_CARDS, blackjack, blackjack_stick_on_20_policy
from policylab.problems.generators import random_mdp
from policylab.problems.notes import (
    MOUNTAIN_GRID,
    SLIPPERY_GRID,
    mountain_gridworld,
    mountain_gridworld_bad_policy,
    recycling_robot,
    recycling_robot_deterministic_policy,
    recycling_robot_stochastic_policy,
    slippery_gridworld,
)
from policylab.problems.registry import (
    ProblemSpec,
    get_problem,
    list_problems,
    problem,
    register_problem,
)
from policylab.problems.sutton_barto import (
    gamblers_bold_policy,
    gamblers_problem,
    gridworld_4x4,
    gridworld_5x5,
    jacks_car_rental,
    jacks_no_move_policy,
)
from policylab.problems.td_examples import (
    CLIFF_GRID,
    WINDY_GRID,
    WINDY_WIND,
    cliff_walking,
    maximization_bias,
    random_walk,
    random_walk_true_values,
    windy_gridworld,
)

__all__ = [
    "BLACKJACK_CARDS",
    "CLIFF_GRID",
    "MOUNTAIN_GRID",
    "SLIPPERY_GRID",
    "WINDY_GRID",
    "WINDY_WIND",
    "ProblemSpec",
    "blackjack",
    "blackjack_stick_on_20_policy",
    "cliff_walking",
    "forest_management",
    "gamblers_bold_policy",
    "gamblers_problem",
    "get_problem",
    "gridworld_4x4",
    "gridworld_5x5",
    "inventory_management",
    "jacks_car_rental",
    "jacks_no_move_policy",
    "list_problems",
    "maximization_bias",
    "mountain_gridworld",
    "mountain_gridworld_bad_policy",
    "problem",
    "random_mdp",
    "random_walk",
    "random_walk_true_values",
    "recycling_robot",
    "recycling_robot_deterministic_policy",
    "recycling_robot_stochastic_policy",
    "register_problem",
    "slippery_gridworld",
    "windy_gridworld",
]
