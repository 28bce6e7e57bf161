"""`policylab learn` for every TD algorithm (design.md's --json contract), bad input,
and the tour's TD sections."""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl
from policylab import tabular as tab
from policylab.cli.main import main
from policylab.exceptions import InvalidArgumentError, InvalidPolicyError

CASES = [
    ("td0", "random-walk", ["--init", "0.5"]),
    ("n-step-td", "random-walk", ["--n", "3"]),
    ("td-lambda", "random-walk", ["--lambda", "0.5", "--trace", "replacing"]),
    ("sarsa", "cliff-walking", ["--alpha", "0.5"]),
    ("q-learning", "FrozenLake-v1", ["--alpha", "1/n", "--epsilon", "exp:1,0.99,0.05"]),
    ("expected-sarsa", "windy-gridworld", []),
    ("double-q-learning", "maximization-bias", []),
    ("n-step-sarsa", "windy-gridworld", ["--n", "4"]),
    ("sarsa-lambda", "cliff-walking", ["--lambda", "0.8"]),
    ("dyna-q", "windy-gridworld", ["--planning-steps", "5", "--env"]),
]


def run_ok(args):
    try:
        main(args)
    except SystemExit as exc:
        assert exc.code in (0, None)


def run_json(capsys, args):
    run_ok(args)
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(("algo", "problem", "extra"), CASES)
def test_learn_json_contract(algo, problem, extra, capsys):
    out = run_json(
        capsys, ["learn", algo, problem, "--episodes", "20", "--seed", "1", "--json", *extra]
    )
    keys = {
        "states",
        "actions",
        "q",
        "v",
        "policy",
        "episodes",
        "steps",
        "seconds",
        "episode_returns",
        "error",
    }
    assert keys <= set(out)
    S, A = len(out["states"]), len(out["actions"])
    assert np.asarray(out["q"]).shape == (S, A)
    assert len(out["v"]) == S
    assert out["episodes"] == 20 and len(out["episode_returns"]) == 20
    assert out["steps"] >= 20
    assert set(out["error"]) == {"max", "rms", "optimal_actions"}


def test_learn_json_matches_the_api(capsys):
    out = run_json(
        capsys,
        [
            "learn",
            "sarsa",
            "cliff-walking",
            "--episodes",
            "30",
            "--alpha",
            "0.5",
            "--seed",
            "3",
            "--json",
        ],
    )
    res = tab.sarsa(pl.problems.cliff_walking(), episodes=30, alpha=0.5, seed=3)
    np.testing.assert_allclose(out["q"], res.q)
    assert out["episode_returns"] == res.episode_returns.tolist()
    assert out["steps"] == res.steps


def test_learn_human_output(capsys):
    run_ok(["learn", "q-learning", "cliff-walking", "--episodes", "20", "--seed", "0"])
    out = capsys.readouterr().out
    assert "q-learning" in out and "q*" in out


@pytest.mark.parametrize(
    "args",
    [
        ["learn", "n-step-sarsa", "cliff-walking", "--n", "0"],
        ["learn", "sarsa-lambda", "cliff-walking", "--lambda", "1.5"],
        ["learn", "td-lambda", "random-walk", "--trace", "dutch"],
        ["learn", "q-learning", "cliff-walking", "--alpha", "2"],
        ["learn", "q-learning", "cliff-walking", "--epsilon", "often"],
        ["learn", "dyna-q", "cliff-walking", "--planning-steps", "-1"],
        ["learn", "sarsa", "no-such-problem"],
    ],
)
def test_learn_bad_input_exits_2_with_one_line(args, capsys):
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("policylab: error:") and "\n" not in err and "Traceback" not in err


def test_api_bad_input_names_the_problem():
    mdp = pl.problems.cliff_walking()
    with pytest.raises(InvalidArgumentError, match="positive integer"):
        tab.sarsa(mdp, episodes=0)
    with pytest.raises(InvalidArgumentError, match="control method"):
        tab.seed_study("sarsa", mdp, 2, episodes=1, policy=pl.Policy.uniform(mdp))
    with pytest.raises(InvalidArgumentError, match="Discrete"):
        tab.q_learning(gym.make("CartPole-v1"), episodes=1)
    with pytest.raises(InvalidPolicyError):
        tab.td0(pl.problems.random_walk(), np.ones((7, 2)), episodes=1)
    with pytest.raises(InvalidArgumentError, match="unknown TD algorithm"):
        tab.seed_study("td1000", mdp, 2)
    with pytest.raises(InvalidArgumentError, match="unknown options"):
        tab.seed_study("sarsa", mdp, 2, episodes=2, lam=0.5)
    with pytest.raises(InvalidArgumentError, match="gamma"):
        tab.q_learning(mdp, gamma=1.5)


def test_general_path_on_a_gymnasium_id_with_a_model():
    """FrozenLake-v1 through Gymnasium itself: the model P gives the error against q*."""
    res = tab.q_learning(gym.make("FrozenLake-v1"), episodes=200, seed=0)
    assert res.params["path"] == "gymnasium"
    assert res.error_target == "q*" and res.error is not None
    assert res.steps >= 200


def test_tour_td_sections_run_quick(tmp_path: Path):
    from rich.console import Console

    from policylab.cli.tour import TourContext, sections

    console = Console(record=True, width=100)
    ctx = TourContext(console=console, out_dir=tmp_path, quick=True)
    ran = [
        fn(ctx) or title for _, title, fn in sections() if fn.__module__ == "policylab.cli.tour_td"
    ]
    assert len(ran) == 2
    text = console.export_text()
    assert "v*(start)" in text and "q-learning" in text


def test_general_path_indexes_observations_by_the_model_labels(capsys):
    """Blackjack-v1's tuple observations, indexed by the exact model's state labels."""
    out = run_json(capsys, ["learn", "q-learning", "Blackjack-v1", "--episodes", "300", "--json"])
    assert len(out["states"]) == pl.problems.blackjack().n_states
    assert out["error"] is not None and len(out["episode_returns"]) == 300


def test_divergence_is_reported_not_silent():
    mdp = pl.problems.random_walk(19, left_reward=-1.0)
    with pytest.warns(RuntimeWarning, match="diverged"):
        tab.td_lambda(mdp, lam=0.9, alpha=0.8, episodes=50, seed=0)
