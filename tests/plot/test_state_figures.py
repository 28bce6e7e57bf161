"""Figures of problems that are not gridworlds: bars, lines, policy maps, Blackjack."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import blackjack_like, car_rental, evaluate, gambler, optimal, random_walk

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.plot import (
    blackjack_figure,
    line_figure,
    policy_map_figure,
    small_mdp_figure,
)


def _ax(fig, title):
    return next(a for a in fig.axes if a.get_title().startswith(title))


def test_recycling_robot_bars_and_tables_show_the_numbers():
    mdp = pl.problems.recycling_robot()
    pi = pl.problems.recycling_robot_stochastic_policy(mdp)
    v = evaluate(mdp, pi)
    fig = small_mdp_figure(mdp, v, pi, q=np.zeros((2, 3)))
    bars = _ax(fig, "state values")
    heights = [p.get_height() for p in bars.patches]
    np.testing.assert_allclose(heights, v)
    table = _ax(fig, "policy")
    texts = [t.get_text() for t in table.texts]
    # The notes' stochastic policy in low: recharge 0.5, wait 0.4, search 0.1; search
    # is the only choice in high, where recharge is unavailable ("—").
    assert texts == ["1.00", "0.00", "—", "0.10", "0.40", "0.50"]


def test_gambler_line_figure_draws_v_and_the_stake():
    mdp = gambler(goal=20)
    v, _, pi = optimal(mdp)
    fig = line_figure(mdp, v, pi)
    ax_v = _ax(fig, "state values")
    x, y = ax_v.lines[0].get_data()
    np.testing.assert_array_equal(x, np.arange(1, 20))  # terminal 0 and 20 left out
    np.testing.assert_allclose(y, v[1:20])
    stakes = [p.get_height() for p in _ax(fig, "policy").patches]
    assert stakes == [mdp.actions[a] for a in pi.action_indices()[1:20]]
    assert ax_v.get_xlabel() == "" and fig.axes[-1].get_xlabel() == "capital"


def test_random_walk_has_no_policy_panel_and_names_its_states():
    mdp = random_walk()
    v = evaluate(mdp, pl.Policy.uniform(mdp))
    np.testing.assert_allclose(v[1:6], np.arange(1, 6) / 6)  # the book's 1/6 .. 5/6
    fig = line_figure(mdp, v, pl.Policy.uniform(mdp), extra_values={"estimate": v * 0.9})
    assert len(fig.axes) == 1
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == list("ABCDE")


def test_policy_map_of_a_two_dimensional_state_space():
    mdp = car_rental(n=5)
    v, _, pi = optimal(mdp)
    fig = policy_map_figure(mdp, v, pi)
    ax = _ax(fig, "policy")
    assert ax.get_xlabel() == "cars at the second location"
    assert ax.get_ylabel() == "cars at the first location"
    img = ax.images[0].get_array()
    i, j = 3, 1  # state (3, 1): row 3, column 1 of the image (origin at the bottom)
    assert img[i, j] == mdp.actions[pi.action_indices()[mdp.state_index((3, 1))]]


def test_blackjack_layout_from_state_labels():
    mdp = blackjack_like()
    v, _, pi = optimal(mdp)
    fig = blackjack_figure(mdp, v, pi)
    titles = [a.get_title() for a in fig.axes if a.get_title()]
    assert titles == [
        "v(s), usable ace",
        "policy π(s), usable ace",
        "v(s), no usable ace",
        "policy π(s), no usable ace",
    ]
    ax = _ax(fig, "v(s), usable ace")
    img = ax.images[0].get_array()
    # Rows are player sums 12..21, columns dealer cards A..10.
    assert img[21 - 12, 0] == pytest.approx(v[mdp.state_index((21, 1, True))])
    assert [t.get_text() for t in ax.get_xticklabels()][:2] == ["A", "2"]


def test_refusals_name_what_is_missing():
    mountain = pl.problems.mountain_gridworld()
    robot = pl.problems.recycling_robot()
    with pytest.raises(InvalidArgumentError, match=r"meta\['x'\]"):
        line_figure(robot, np.zeros(2))
    with pytest.raises(InvalidArgumentError, match="gridworld"):
        policy_map_figure(mountain, np.zeros(9))
    with pytest.raises(InvalidArgumentError, match="no grid layout"):
        policy_map_figure(robot, np.zeros(2))
    with pytest.raises(InvalidArgumentError, match="Blackjack"):
        blackjack_figure(mountain, np.zeros(9))
    big = gambler(goal=100)
    with pytest.raises(InvalidArgumentError, match="at most 40 states"):
        small_mdp_figure(big, np.zeros(101))
    with pytest.raises(InvalidArgumentError, match="single action"):
        line_figure(random_walk(), policy=pl.Policy.uniform(random_walk()))
