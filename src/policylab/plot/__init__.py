"""Figures of policylab (matplotlib, headless): what the notes show, as pictures.

``import policylab`` never imports matplotlib; this package does, when first used
(``policylab.plot`` or ``import policylab.plot``).

The two entry points other modules (and the command line) call::

    from policylab.plot import save_solution_figure, save_learning_figure
    save_solution_figure(mdp, v, policy, "runs/mountain.png")   # picks the figure
    save_learning_figure({"MC": runs, "Q-learning": runs2}, "runs/learning.svg")

and the figures themselves, each returning a :class:`matplotlib.figure.Figure`:

- :func:`gridworld_figure`: values as a heatmap with numbers, the policy as
  arrows, the Q-table as triangles (any ``mdp.grid`` with moves);
- :func:`q_table_figure`: the notes' figure 9, optionally beside the exact q;
- :func:`small_mdp_figure`: bars and table images (recycling robot);
- :func:`line_figure`: 1-D problems (``meta["x"]``: gambler, random walk);
- :func:`policy_map_figure`: 2-D state spaces (car rental, Figure 4.2);
- :func:`blackjack_figure`: Figure 5.2's layout;
- :func:`learning_figure`: error and return curves, mean and bootstrap band;
- :func:`episode_figure`: one episode's path on the grid (notes' figures 7, 8);
- :func:`interaction_loop_figure`: the agent-environment loop (notes' figure 1);
- :func:`aggregate_intervals_figure`, :func:`performance_profile_figure`,
  :func:`run_curves_figure`: statistics over runs and tasks (IQM and its interval,
  performance profiles, learning curves with bands).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from policylab.exceptions import InvalidArgumentError
from policylab.plot._common import save_figure
from policylab.plot.diagrams import interaction_loop_figure
from policylab.plot.grid import (
    draw_grid_policy,
    draw_grid_values,
    draw_q_table,
    episode_figure,
    gridworld_figure,
    q_table_figure,
)
from policylab.plot.learning import (
    LearningCurves,
    bootstrap_ci,
    draw_mean_with_band,
    learning_curves,
    learning_figure,
    moving_average,
)
from policylab.plot.scores import (
    aggregate_intervals_figure,
    align_curves,
    performance_profile_figure,
    run_curves_figure,
)
from policylab.plot.states import (
    MAX_TABLE_STATES,
    blackjack_figure,
    draw_policy_table,
    draw_value_bars,
    line_figure,
    policy_map_figure,
    small_mdp_figure,
)
from policylab.validation import check_figure_path

if TYPE_CHECKING:
    from matplotlib.figure import Figure
    from numpy.typing import ArrayLike

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = [
    "LearningCurves",
    "aggregate_intervals_figure",
    "align_curves",
    "blackjack_figure",
    "bootstrap_ci",
    "draw_grid_policy",
    "draw_grid_values",
    "draw_mean_with_band",
    "draw_policy_table",
    "draw_q_table",
    "draw_value_bars",
    "episode_figure",
    "figure_kind",
    "gridworld_figure",
    "interaction_loop_figure",
    "learning_curves",
    "learning_figure",
    "line_figure",
    "moving_average",
    "performance_profile_figure",
    "policy_map_figure",
    "q_table_figure",
    "run_curves_figure",
    "save_figure",
    "save_learning_figure",
    "save_solution_figure",
    "small_mdp_figure",
    "solution_figure",
]


def figure_kind(mdp: FiniteMDP) -> str:
    """Which solution figure fits a problem.

    Returns:
        ``"blackjack"`` (``meta["blackjack"]``), ``"gridworld"`` (a grid with moves),
        ``"policy_map"`` (a grid without moves), ``"line"`` (``meta["x"]``) or
        ``"small"`` (at most :data:`MAX_TABLE_STATES` states).

    Raises:
        InvalidArgumentError: If no figure fits (a large problem with no layout).
    """
    if mdp.meta.get("blackjack"):
        return "blackjack"
    if mdp.grid is not None:
        return "gridworld" if mdp.grid.moves else "policy_map"
    if "x" in mdp.meta:
        return "line"
    if mdp.n_states <= MAX_TABLE_STATES:
        return "small"
    raise InvalidArgumentError(
        f"no solution figure fits {mdp.name!r}: it has {mdp.n_states} states and no layout to "
        "draw them by (mdp.grid for grid-shaped problems, mdp.meta['x'] for 1-D ones, "
        f"mdp.meta['blackjack']); without one, figures show at most {MAX_TABLE_STATES} states"
    )


def solution_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None,
    policy: Policy | ArrayLike | None,
    *,
    title: str | None = None,
    q: ArrayLike | None = None,
    ties: bool = False,
) -> Figure:
    """The figure that fits the problem (see :func:`figure_kind`), drawing v and the policy.

    With ``ties=True`` and ``q`` given, a gridworld's policy panel draws every action
    that is greedy under ``q`` (:func:`policylab.optimal_actions`: with q = q_*, all
    optimal actions), as Sutton & Barto's Figure 3.5 does, rather than ``policy``'s one
    action per state.

    ``q`` is drawn where the figure has a view for it (the gridworld's Q-table, the
    small problem's table) and otherwise left out.
    """
    kind = figure_kind(mdp)
    if v is None and policy is None and q is None:
        raise InvalidArgumentError("a solution figure needs at least one of v, policy or q")
    if kind == "blackjack":
        return blackjack_figure(mdp, v, policy, title=title)
    if kind == "gridworld":
        if ties and q is not None:
            from policylab.planning import optimal_actions

            policy = optimal_actions(mdp, q)
        if q is not None:
            from policylab.plot.grid import q_triangles, require_grid

            try:
                q_triangles(require_grid(mdp, "the Q-table view"), mdp)
            except InvalidArgumentError:
                q = None  # moves other than the compass four: no triangle view
        return gridworld_figure(mdp, v, policy, q=q, title=title)
    if kind == "policy_map":
        return policy_map_figure(mdp, v, policy, title=title)
    if kind == "line":
        return line_figure(mdp, v, policy, title=title)
    return small_mdp_figure(mdp, v, policy, q=q, title=title)


def save_solution_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None,
    policy: Policy | ArrayLike | None,
    path: str | Path,
    *,
    title: str | None = None,
    q: ArrayLike | None = None,
    ties: bool = False,
) -> Path:
    """Draw a solution with the figure that fits the problem and save it.

    PNG by default; SVG or PDF when ``path`` ends in ``.svg`` or ``.pdf``. ``ties``: see
    :func:`solution_figure`.

    Returns:
        The path written.

    Raises:
        InvalidArgumentError: If no figure fits the problem, or the suffix is unknown.
    """
    _check_suffix(path)
    fig = solution_figure(mdp, v, policy, title=title, q=q, ties=ties)
    return save_figure(fig, path)


def save_learning_figure(results: Any, path: str | Path, *, title: str | None = None) -> Path:
    """Draw learning curves (see :func:`learning_figure`) and save them.

    Args:
        results: One learner result, or ``{label: [result per seed]}``.
        path: Where to write (PNG by default, SVG/PDF by suffix).
        title: Figure title.

    Returns:
        The path written.
    """
    _check_suffix(path)
    return save_figure(learning_figure(results, title=title), path)


def _check_suffix(path: str | Path) -> None:
    check_figure_path(path)
