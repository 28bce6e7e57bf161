"""`policylab sweep` / `tune` bad input: exit 2, one line naming what was wrong, no Ray work.

And the parsing of --set, --param and the algorithm's own options against hand-written
expectations.
"""

from __future__ import annotations

import json
import socket
import time

import pytest

from policylab.cli.main import main
from policylab.cluster import parse_address
from policylab.exceptions import InvalidArgumentError
from policylab.experiments import build_spec, config_label, parse_distribution, parse_option_tokens
from policylab.experiments import parse_set as parse_set_values


def run(capsys, *argv: str) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exc:
        main(list(argv))
        raise SystemExit(0)
    out = capsys.readouterr()
    return int(exc.value.code or 0), out.out, out.err


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["sweep", "q-lerning", "CliffWalking-v1"], "did you mean 'q-learning'"),
        (["sweep", "q-learning", "no-such-problem"], "unknown problem"),
        (["sweep", "q-learning", "CliffWalking-v1", "--alpa", "0.1"], "did you mean '--alpha'"),
        (["sweep", "q-learning", "CliffWalking-v1", "--seed", "3"], "--seeds"),
        (["sweep", "q-learning", "CliffWalking-v1", "--set", "alpah=0.1,0.2"], "'alpha'"),
        (["sweep", "q-learning", "CliffWalking-v1", "--set", "alpha"], "KEY=V1,V2"),
        (["sweep", "q-learning", "CliffWalking-v1", "--set", "alpha=0.1,7"], "alpha"),
        (["sweep", "q-learning", "CliffWalking-v1", "--episodes", "x"], "--episodes"),
        (["sweep", "ppo", "CartPole-v1", "--set", "learning_rat=1e-3,1e-4"], "learning_rate"),
        (["sweep", "ppo", "CartPole-v1", "--set", "n_envs=0,2"], "n_envs"),
        (["sweep", "ppo", "NoSuchEnv-v0"], "NoSuchEnv-v0"),
        (["sweep", "ppo", "CartPole-v1", "--alpha", "0.1"], "--alpha"),
        (["sweep", "q-learning", "CliffWalking-v1", "--seeds", "0"], "--seeds"),
        (["sweep", "q-learning", "CliffWalking-v1", "--address", "nohost:"], "--address"),
        (["sweep"], "ALGO and PROBLEM"),
        (["tune", "q-learning", "CliffWalking-v1"], "--param"),
        (["tune", "q-learning", "CliffWalking-v1", "--param", "alpha=normal:0,1"], "uniform"),
        (["tune", "q-learning", "CliffWalking-v1", "--param", "alpha=uniform:1,0"], "LOW"),
        (["tune", "q-learning", "CliffWalking-v1", "--param", "alpha=loguniform:0,1"], "> 0"),
        (["tune", "q-learning", "CliffWalking-v1", "--param", "alpah=uniform:0,1"], "'alpha'"),
        (
            [
                "tune",
                "q-learning",
                "CliffWalking-v1",
                "--param",
                "alpha=uniform:0.1,0.5",
                "--scheduler",
                "hyperband",
            ],
            "--scheduler",
        ),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, argv, needle):
    code, out, err = run(capsys, *argv, "--out", str(tmp_path / "o"))
    assert code == 2, err
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("policylab: error:"), err
    assert needle in lines[0]
    assert not (tmp_path / "o" / "sweep.json").exists()


def test_an_unreachable_address_is_refused_within_seconds(capsys, tmp_path):
    t0 = time.monotonic()
    code, _, err = run(
        capsys, "sweep", "q-learning", "CliffWalking-v1", "--address",
        f"127.0.0.1:{_free_port()}", "--out", str(tmp_path / "o"),
    )  # fmt: skip
    assert code == 2 and "cannot reach a Ray cluster" in err
    assert len(err.strip().splitlines()) == 1
    assert time.monotonic() - t0 < 30  # a refusal, not a hang (generous for a loaded machine)
    assert not (tmp_path / "o").exists()


def test_folders_that_are_not_sweeps_are_refused(capsys, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    (other / "run.json").write_text("{}")
    code, _, err = run(capsys, "sweep", "q-learning", "CliffWalking-v1", "--out", str(other))
    assert code == 2 and "not empty and holds no sweep" in err
    code, _, err = run(capsys, "sweep", "--resume", str(other))
    assert code == 2 and "no sweep.json" in err
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "sweep.json").write_text(json.dumps({"kind": "something-else"}))
    code, _, err = run(capsys, "tune", "--resume", str(fake))
    assert code == 2 and "not a policylab sweep" in err
    code, _, err = run(capsys, "sweep", "q-learning", "--resume", str(fake))
    assert code == 2 and "leave out q-learning" in err
    code, _, err = run(capsys, "sweep", "q-learning", "CliffWalking-v1", "--out", str(fake))
    assert code == 2 and "--resume" in err


def test_option_tokens_parse_like_learn():
    got = parse_option_tokens(
        "q-learning", ["--episodes", "300", "--alpha=1/n", "--epsilon", "0.2", "--gamma", "0.9"]
    )
    assert got == {"episodes": 300, "alpha": "1/n", "epsilon": 0.2, "gamma": 0.9}
    assert parse_option_tokens("ppo", ["--steps", "5000"]) == {"steps": 5000}
    with pytest.raises(InvalidArgumentError, match="needs a value"):
        parse_option_tokens("q-learning", ["--alpha"])


def test_set_param_and_labels():
    assert parse_set_values(["alpha=0.1,0.5", "trace=replacing"]) == {
        "alpha": [0.1, 0.5],
        "trace": ["replacing"],
    }
    assert parse_distribution("lr=loguniform:1e-4,1e-2") == (
        "lr",
        {"kind": "loguniform", "low": 1e-4, "high": 1e-2},
    )
    assert parse_distribution("n=int:1,8") == ("n", {"kind": "int", "low": 1, "high": 8})
    assert parse_distribution("act=choice:tanh,relu") == (
        "act",
        {"kind": "choice", "values": ["tanh", "relu"]},
    )
    assert config_label({}) == "default"
    assert config_label({"alpha": 0.1, "n": 4}) == "alpha=0.1,n=4"
    spec = build_spec(
        "sweep", "q-learning", "cliff-walking", seeds=3,
        set_values={"alpha": [0.1, 0.5], "epsilon": [0.2]},
    )  # fmt: skip
    assert spec.seeds == [0, 1, 2]
    assert spec.fixed == {"epsilon": 0.2} and spec.grid == {"alpha": [0.1, 0.5]}
    assert spec.configurations() == [{"alpha": 0.1}, {"alpha": 0.5}]


def test_addresses():
    assert parse_address("10.0.0.5:6379") == ("10.0.0.5", 6379)
    assert parse_address("ray://head") == ("head", 10001)
    assert parse_address("auto") is None
    with pytest.raises(InvalidArgumentError):
        parse_address("head:99999")
