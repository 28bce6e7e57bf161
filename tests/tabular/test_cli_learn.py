import json

import pytest

from policylab.cli.main import main
from policylab.tabular import list_algorithms


def run(capsys, *argv):
    try:
        main(list(argv))
        code = 0
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_registry_lists_mc_algorithms():
    names = {spec.name for spec in list_algorithms()}
    assert {"mc-prediction", "mc-control", "mc-off-policy"} <= names


@pytest.mark.parametrize(
    "argv",
    [
        ["mc-prediction", "slippery-gridworld", "--every-visit"],
        ["mc-control", "slippery-gridworld", "--exploring-starts"],
        ["mc-control", "slippery-gridworld", "--epsilon", "exp:1,0.99,0.05", "--alpha", "0.05"],
        ["mc-off-policy", "slippery-gridworld", "--weighted"],
        ["mc-off-policy", "blackjack", "--target", "stick-on-20"],
    ],
)
def test_learn_json_contract(capsys, argv):
    code, out, _ = run(capsys, "learn", *argv, "--episodes", "300", "--seed", "1", "--json")
    assert code == 0
    d = json.loads(out)
    assert set(d) == {
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
    assert d["episodes"] == 300 and len(d["episode_returns"]) == 300
    assert len(d["q"]) == len(d["states"]) and len(d["q"][0]) == len(d["actions"])
    assert set(d["error"]) == {"max", "rms", "optimal_actions"}
    _, out2, _ = run(capsys, "learn", *argv, "--episodes", "300", "--seed", "1", "--json")
    d2 = json.loads(out2)
    assert d2["q"] == d["q"]  # same seed, same result


def test_learn_tables_and_gymnasium_general_path(capsys):
    code, out, _ = run(
        capsys, "learn", "mc-prediction", "slippery-gridworld", "-n", "200", "--seed", "0"
    )
    assert code == 0 and "Q(s, up)" in out and "Error against the exact q_pi" in out
    code, out, _ = run(
        capsys,
        "learn",
        "mc-control",
        "Blackjack-v1",
        "-n",
        "200",
        "--seed",
        "0",
        "--epsilon",
        "0.1",
        "--json",
    )
    d = json.loads(out)
    assert code == 0 and d["error"] is not None and "(13, 2, True)" in d["states"]
    code, out, _ = run(
        capsys, "learn", "mc-prediction", "slippery-gridworld", "--env", "-n", "50", "--json"
    )
    assert code == 0 and json.loads(out)["episodes"] == 50


@pytest.mark.parametrize(
    ("argv", "msg"),
    [
        (["mc-control", "no-such-problem"], "unknown problem"),
        (["mc-control", "slippery-gridworld", "--epsilon", "fast"], "cannot read schedule"),
        (["mc-control", "slippery-gridworld", "--episodes", "0"], "episodes"),
        (["mc-prediction", "recycling-robot"], "episodic"),
        (["mc-prediction", "slippery-gridworld", "--policy", "nope"], "unknown policy"),
        (["mc-control", "CartPole-v1"], "discrete or hashable"),
        (["mc-control", "slippery-gridworld", "--epsilon-by", "step"], "epsilon_by"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, argv, msg):
    code, _, err = run(capsys, "learn", *argv)
    assert code == 2
    assert msg in err and "Traceback" not in err and err.strip().count("\n") == 0
