"""Gridworld figures: numbers in the right cells, arrows, Q triangles, refusals."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.patches import FancyArrow
from synthetic import action_values, evaluate, optimal

import policylab as pl
from policylab.exceptions import InvalidArgumentError, InvalidPolicyError, ShapeError
from policylab.plot import (
    draw_q_table,
    gridworld_figure,
    q_table_figure,
    save_figure,
    save_solution_figure,
)


def _ax(fig, title):
    return next(a for a in fig.axes if a.get_title().startswith(title))


def _texts_at(ax, x, y):
    return [t.get_text() for t in ax.texts if np.allclose(t.get_position(), (x, y))]


def test_mountain_bad_policy_values_are_written_in_their_cells(tmp_path):
    mdp = pl.problems.mountain_gridworld()
    pi = pl.problems.mountain_gridworld_bad_policy(mdp)
    v = evaluate(mdp, pi)
    fig = gridworld_figure(mdp, v, pi)
    ax_v, ax_pi = _ax(fig, "state values"), _ax(fig, "policy")
    # The notes: -6 from the start (row 2, column 0), -5 from the cell to its right.
    assert _texts_at(ax_v, 0, 2) == ["-6"]
    assert _texts_at(ax_v, 1, 2) == ["-5"]
    assert _texts_at(ax_v, 2, 2) == ["0"]  # the goal is terminal
    kinds = {t.get_text() for t in ax_v.texts}
    assert {"mountain", "goal", "start"} <= kinds
    # One arrow per non-terminal cell, pointing along the policy's move.
    arrows = [p for p in ax_pi.patches if isinstance(p, FancyArrow)]
    assert len(arrows) == int((~mdp.terminal).sum())
    path = save_figure(fig, tmp_path / "bad.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("move", "sign"), [("up", -1), ("down", 1)])
def test_arrow_directions_follow_grid_moves(move, sign):
    mdp = pl.problems.mountain_gridworld()
    pi = pl.Policy.deterministic(
        mdp, {s: move for s in mdp.states if not mdp.terminal[mdp.state_index(s)]}
    )
    fig = gridworld_figure(mdp, policy=pi)
    for arrow in fig.axes[0].patches:
        if isinstance(arrow, FancyArrow):
            xy = arrow.get_xy()
            assert np.ptp(xy[:, 0]) < np.ptp(xy[:, 1])  # vertical
            # The head's corners (widest points) lie on the side the arrow points to
            # (row 0 is at the top, so "up" is towards smaller y).
            corner = xy[np.abs(xy[:, 0] - xy[:, 0].mean()).argmax()]
            assert np.sign(corner[1] - xy[:, 1].mean()) == sign


def test_stochastic_policy_draws_one_arrow_per_action_with_probabilities():
    mdp = pl.problems.slippery_gridworld()
    fig = gridworld_figure(mdp, policy=pl.Policy.uniform(mdp))
    ax = fig.axes[0]
    arrows = [p for p in ax.patches if isinstance(p, FancyArrow)]
    assert len(arrows) == 3 * 4
    assert sum(t.get_text() == "0.25" for t in ax.texts) == 12


def test_all_optimal_actions_of_figure_3_5_are_drawn_with_equal_arrows():
    # Sutton & Barto Figure 3.5 (right): in the 5 x 5 gridworld's top-left cell the only
    # optimal move is right; in A (row 0, column 1) all four moves tie (each jumps to
    # A'); in the bottom-left cell, up and right tie.
    mdp = pl.problems.gridworld_5x5()
    res = pl.value_iteration(mdp, tol=1e-10)
    ties = pl.optimal_actions(mdp, res.q)
    fig = gridworld_figure(mdp, res.v, ties)
    ax = _ax(fig, "greedy actions")
    arrows = [p for p in ax.patches if isinstance(p, FancyArrow)]
    assert len(arrows) == int(ties.sum())
    assert ties[mdp.state_index((0, 1))].sum() == 4
    assert [mdp.actions[a] for a in np.flatnonzero(ties[mdp.state_index((4, 0))])] == [
        "up",
        "right",
    ]
    lengths = {round(float(np.ptp(a.get_xy(), axis=0).max()), 6) for a in arrows}
    assert len(lengths) == 1  # one arrow length: a set of actions, not probabilities
    assert not any(t.get_text() == "0.5" for t in ax.texts)


def test_solution_figure_with_ties_draws_the_tie_set(tmp_path):
    mdp = pl.problems.gridworld_5x5()
    res = pl.value_iteration(mdp, tol=1e-10)
    from policylab.plot import solution_figure

    one = solution_figure(mdp, res.v, res.policy, q=res.q)
    every = solution_figure(mdp, res.v, res.policy, q=res.q, ties=True)
    n_one = sum(isinstance(p, FancyArrow) for p in _ax(one, "policy").patches)
    n_all = sum(isinstance(p, FancyArrow) for p in _ax(every, "greedy actions").patches)
    assert n_one == mdp.n_states  # no terminal state: one arrow per cell
    assert n_all == int(pl.optimal_actions(mdp, res.q).sum()) > n_one


def test_an_action_set_is_the_uniform_policy_over_it_in_other_figures():
    from policylab.plot._common import policy_probs

    mdp = pl.problems.gamblers_problem()
    res = pl.value_iteration(mdp)
    ties = pl.optimal_actions(mdp, res.q)
    probs = policy_probs(mdp, ties)
    live = ~mdp.terminal
    np.testing.assert_allclose(probs[live].sum(axis=1), 1.0)
    rows, _ = np.nonzero(ties)
    np.testing.assert_allclose(probs[ties], 1.0 / ties.sum(axis=1)[rows])


def test_q_table_triangles_hold_q_and_mark_the_greedy_action():
    mdp = pl.problems.slippery_gridworld()
    v = evaluate(mdp, pl.Policy.uniform(mdp))
    q = action_values(mdp, v)
    fig = q_table_figure(mdp, q, reference=q, labels=("Monte Carlo", "exact"))
    ax = fig.axes[0]
    polys = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(polys[0].get_paths()) == 3 * 4  # three live cells, four moves each
    bold = [t.get_text() for t in ax.texts if t.get_fontweight() == "bold"]
    live = np.flatnonzero(~mdp.terminal)
    assert sorted(bold) == sorted(f"{q[s].max():.1f}" for s in live)
    assert "max |Monte Carlo − exact| = 0" in fig._supxlabel.get_text()


def test_gymnasium_gridworlds_carry_their_layout(tmp_path):
    lake = pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=0.95)
    assert lake.grid is not None and lake.grid.shape == (4, 4)
    assert lake.grid.kinds[(1, 1)] == "hole" and lake.grid.kinds[(3, 3)] == "goal"
    # Action 0 of FrozenLake is left, 3 is up.
    assert lake.grid.moves[0] == (0, -1) and lake.grid.moves[3] == (-1, 0)
    v, q, pi = optimal(lake)
    assert save_solution_figure(lake, v, pi, tmp_path / "lake.png", q=q).stat().st_size > 0
    cliff = pl.FiniteMDP.from_gymnasium("CliffWalking-v1")
    assert cliff.grid.shape == (4, 12) and cliff.grid.kinds[(3, 5)] == "cliff"
    assert cliff.grid.moves[0] == (-1, 0)
    v, q, pi = optimal(cliff)
    fig = gridworld_figure(cliff, v, pi, q=q)
    assert _texts_at(_ax(fig, "state values"), 0, 3) == [
        "-13"
    ]  # 13 steps along the edge of the cliff


def test_refusals_are_clear():
    robot = pl.problems.recycling_robot()
    with pytest.raises(InvalidArgumentError, match="grid-shaped"):
        gridworld_figure(robot, np.zeros(2))
    mdp = pl.problems.mountain_gridworld()
    with pytest.raises(ShapeError, match=r"expected \(9,\)"):
        gridworld_figure(mdp, np.zeros(4))
    with pytest.raises(InvalidArgumentError, match="at least one"):
        gridworld_figure(mdp)
    other = pl.problems.slippery_gridworld()
    with pytest.raises(InvalidPolicyError, match="other states"):
        gridworld_figure(mdp, policy=pl.Policy.uniform(other))
    with pytest.raises(ShapeError, match="expected"):
        q_table_figure(mdp, np.zeros((9, 3)))


def test_q_table_refuses_moves_other_than_the_compass():
    king = pl.grid_mdp(
        ["..", ".G"],
        {".": "floor", "G": "goal"},
        lambda a, b, k: -1.0,
        moves={"up": (-1, 0), "down": (1, 0), "left": (0, -1), "right": (0, 1), "ne": (-1, 1)},
    )
    with pytest.raises(InvalidArgumentError, match="compass"):
        q_table_figure(king, np.zeros((4, 5)))
    from matplotlib.figure import Figure

    with pytest.raises(InvalidArgumentError, match="compass"):
        draw_q_table(Figure().add_subplot(), king, np.zeros((4, 5)))
    # The solution figure leaves the Q view out rather than failing.
    fig = gridworld_figure(king, np.zeros(4), pl.Policy.uniform(king))
    assert len([a for a in fig.axes if a.get_title()]) == 2


def test_episode_figure_shows_the_path_and_the_return(tmp_path):
    from policylab.plot import episode_figure, interaction_loop_figure

    mdp = pl.problems.mountain_gridworld()
    ep = pl.rollout(mdp, pl.problems.mountain_gridworld_bad_policy(mdp), seed=0)
    fig = episode_figure(mdp, ep)
    table = fig.axes[1].texts[0].get_text()
    assert "G_0 = -6" in table and "(terminated)" in table
    labels = {t.get_text() for t in fig.axes[0].texts}
    assert {str(t) for t in range(1, len(ep) + 1)} <= labels  # every step numbered
    with pytest.raises(InvalidArgumentError, match="grid-shaped"):
        episode_figure(pl.problems.recycling_robot(), ep)
    assert save_figure(interaction_loop_figure(), tmp_path / "loop.png").stat().st_size > 0


def test_windy_gridworld_shows_each_columns_wind():
    mdp = pl.problems.windy_gridworld()
    fig = gridworld_figure(mdp, np.zeros(mdp.n_states))
    labels = [t.get_text() for t in fig.axes[0].get_xticklabels()]
    # Example 6.5: wind 0 0 0 1 1 1 2 2 1 0
    assert labels == [
        "0\n·",
        "1\n·",
        "2\n·",
        "3\n↑1",
        "4\n↑1",
        "5\n↑1",
        "6\n↑2",
        "7\n↑2",
        "8\n↑1",
        "9\n·",
    ]
    assert "wind" in fig.axes[0].get_xlabel()
