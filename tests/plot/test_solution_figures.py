"""The entry points: the right figure for every built-in problem, files, refusals."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from synthetic import blackjack_like, car_rental, gambler, optimal

import policylab as pl
from policylab.exceptions import InvalidArgumentError
from policylab.plot import figure_kind, save_solution_figure, solution_figure

PNG = b"\x89PNG\r\n\x1a\n"


def _builtin():
    for spec in pl.problems.list_problems():
        yield spec.name


@pytest.mark.parametrize("name", list(_builtin()))
def test_every_builtin_problem_gets_its_figure_or_a_clear_refusal(name, tmp_path):
    mdp = pl.problems.get_problem(name)
    res = pl.value_iteration(mdp)
    v, q, pi = res.v, res.q, res.policy
    try:
        kind = figure_kind(mdp)
    except InvalidArgumentError as e:
        assert mdp.name in str(e) and "no solution figure fits" in str(e)
        with pytest.raises(InvalidArgumentError):
            save_solution_figure(mdp, v, pi, tmp_path / "x.png")
        return
    assert kind in {"gridworld", "small", "line", "policy_map", "blackjack"}
    path = save_solution_figure(mdp, v, pi, tmp_path / f"{name}.png", q=q)
    assert path.read_bytes()[:8] == PNG and path.stat().st_size > 1000


@pytest.mark.parametrize(
    ("mdp", "kind"),
    [
        (pl.problems.recycling_robot(), "small"),
        (pl.problems.mountain_gridworld(), "gridworld"),
        (gambler(goal=10), "line"),
        (car_rental(n=4), "policy_map"),
        (blackjack_like(), "blackjack"),
    ],
    ids=["robot", "mountain", "gambler", "car-rental", "blackjack"],
)
def test_the_figure_is_picked_by_the_problem(mdp, kind, tmp_path):
    assert figure_kind(mdp) == kind
    v, q, pi = optimal(mdp)
    assert save_solution_figure(mdp, v, pi, tmp_path / "f.png", q=q).stat().st_size > 0


def test_large_problem_without_layout_is_refused():
    S = 60
    P = np.zeros((1, S, S))
    P[0, np.arange(S), (np.arange(S) + 1) % S] = 1.0
    ring = pl.FiniteMDP.from_arrays(P, np.ones((S, 1)), gamma=0.9)
    with pytest.raises(InvalidArgumentError, match=r"60 states and no layout"):
        solution_figure(ring, np.zeros(S), None)


def test_formats_by_suffix(tmp_path):
    mdp = pl.problems.mountain_gridworld()
    v, _, pi = optimal(mdp)
    assert save_solution_figure(mdp, v, pi, tmp_path / "a.svg").read_text().count("<svg") == 1
    assert save_solution_figure(mdp, v, pi, tmp_path / "sub" / "b").suffix == ".png"
    with pytest.raises(InvalidArgumentError, match=r"'\.jpg'; expected one of \.png, \.svg"):
        save_solution_figure(mdp, v, pi, tmp_path / "c.jpg")
    assert not (tmp_path / "c.jpg").exists()


def test_same_input_same_bytes(tmp_path):
    mdp = pl.problems.slippery_gridworld()
    v, q, pi = optimal(mdp)
    a = save_solution_figure(mdp, v, pi, tmp_path / "a.png", q=q).read_bytes()
    b = save_solution_figure(mdp, v, pi, tmp_path / "b.png", q=q).read_bytes()
    assert a == b


def test_import_policylab_loads_neither_matplotlib_nor_scipy_stats():
    """Both take a second or more to import: the figures and the Poisson problems load them."""
    code = (
        "import sys, policylab, policylab.cli.main\n"
        "assert 'matplotlib' not in sys.modules, 'matplotlib imported'\n"
        "assert 'scipy.stats' not in sys.modules, 'scipy.stats imported'\n"
        "import policylab.plot\n"
        "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot imported'\n"
        "policylab.problems.jacks_car_rental(max_cars=3)\n"
        "assert 'scipy.stats' in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
