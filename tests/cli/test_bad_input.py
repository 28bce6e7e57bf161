"""Bad input on the command line: exit code 2 and one line on stderr, for every case.

Every command is in the one table, the deep-RL ones (train, eval, record) included.

One table, one parametrised test: each row is (argv, expected exit code, words that
the one line on stderr must hold). The commands run in this process through
``main(argv)``; a few run as real ``policylab`` processes too, to check the entry point.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from policylab.cli.main import main

RunCLI = Callable[[list[str]], tuple[int, str, str]]  # the run_cli fixture (conftest.py)


LEARN = ["learn", "q-learning", "recycling-robot"]
SOLVE = ["solve", "recycling-robot"]
TRAIN = ["train", "ppo", "CartPole-v1"]
_BOX2D = importlib.util.find_spec("Box2D") is not None

CASES: list[tuple[list[str], int, list[str]]] = [
    # usage errors: one line, with a hint where one is cheap
    (["learn", "q-lerning", "recycling-robot"], 2, ["No such command", "'q-learning'"]),
    (["solvee", "recycling-robot"], 2, ["No such command", "'solve'"]),
    ([*SOLVE, "--bogus"], 2, ["No such option: --bogus", "policylab solve --help"]),
    (["problems", "--bogus"], 2, ["No such option: --bogus"]),
    (["solve"], 2, ["Missing argument"]),
    (["evaluate", "recycling-robot"], 2, ["Missing option", "--policy"]),
    ([*LEARN, "--episodes", "nan"], 2, ["--episodes", "'nan'"]),
    ([*LEARN, "--seed", "1.5"], 2, ["--seed", "'1.5'"]),
    # numbers out of range, named by their flag
    ([*LEARN, "--seed", "-1"], 2, ["--seed must be a non-negative integer", "got -1"]),
    ([*LEARN, "--seed", "9223372036854775808"], 2, ["--seed", "below 2**63"]),
    ([*LEARN, "--episodes", "100000000000000000000"], 2, ["--episodes", "2**62"]),
    ([*LEARN, "--episodes", "0"], 2, ["--episodes must be", "got 0"]),
    ([*LEARN, "--max-steps", "0"], 2, ["--max-steps must be", "got 0"]),
    ([*LEARN, "--checkpoints", "0"], 2, ["--checkpoints must be a positive integer"]),
    ([*LEARN, "--max-rows", "-1"], 2, ["--max-rows must be an integer >= 0"]),
    ([*LEARN, "--gamma", "1.5"], 2, ["--gamma must be in [0, 1]", "1.5"]),
    ([*LEARN, "--gamma", "nan"], 2, ["--gamma must be a finite number"]),
    ([*LEARN, "--alpha", "2"], 2, ["alpha must stay in [0, 1]"]),
    # schedules: which number is wrong, and why
    ([*LEARN, "--alpha", "exp:1,2"], 2, ["'exp:1,2'", "decay (the second number)", "got 2.0"]),
    ([*LEARN, "--alpha", "linear:1,0.1,0"], 2, ["'linear:1,0.1,0'", "steps (the third number"]),
    ([*LEARN, "--epsilon", "inverse:1,-1,0"], 2, ["'inverse:1,-1,0'", "power must be > 0"]),
    ([*LEARN, "--alpha", "exp:1"], 2, ["has 1 number", "exp takes 2 to 3"]),
    ([*LEARN, "--alpha", "exp:1,x"], 2, ["number 2 ('x') is not a number"]),
    ([*LEARN, "--alpha", "fast"], 2, ["cannot read schedule 'fast'"]),
    # outputs checked before any work
    ([*LEARN, "--plot", "out.xyz"], 2, ["--plot 'out.xyz'", "'.xyz'", ".png, .svg, .pdf"]),
    ([*LEARN, "--plot", "/proc/nope/x.png"], 2, ["--plot '/proc/nope/x.png' cannot be written"]),
    ([*LEARN, "--plot", "/"], 2, ["--plot '/' is a folder"]),
    ([*SOLVE, "--plot", "/proc/nope/x.png"], 2, ["--plot", "cannot be written"]),
    ([*SOLVE, "--plot", "out.xyz"], 2, ["--plot 'out.xyz' ends in '.xyz'"]),
    (["evaluate", "recycling-robot", "--policy", "uniform", "--plot", "a.gif"], 2, ["'.gif'"]),
    (["plot", "optimal", "gridworld-4x4", "--out", "x.xyz"], 2, ["--out 'x.xyz'", "'.xyz'"]),
    (["plot", "values", "gridworld-4x4", "--out", "/proc/nope/x.png"], 2, ["cannot be written"]),
    (["plot", "q-table", "gridworld-4x4", "--out", "/proc/x.png"], 2, ["cannot be written"]),
    (["plot", "q-table", "recycling-robot"], 2, ["the Q-table view needs a grid-shaped problem"]),
    (["tour", "--out", "/proc/nope"], 2, ["--out '/proc/nope' cannot be written"]),
    (["tour", "--out", "/proc/version"], 2, ["is an existing file; expected a folder"]),
    (["tour", "--seed", "-1"], 2, ["--seed must be a non-negative integer"]),
    # planning options
    ([*SOLVE, "--tol", "0"], 2, ["--tol must be > 0", "got 0.0"]),
    ([*SOLVE, "--tol", "nan"], 2, ["--tol must be a finite number"]),
    ([*SOLVE, "--gamma", "-0.1"], 2, ["--gamma must be in [0, 1]", "-0.1"]),
    ([*SOLVE, "--max-rows", "-1"], 2, ["--max-rows must be an integer >= 0"]),
    ([*SOLVE, "--method", "vii"], 2, ["--method must be one of", "did you mean 'vi'"]),
    (["evaluate", "recycling-robot", "--policy", "uniform", "--method", "exakt"], 2, ["'exact'"]),
    (["plot", "optimal", "gridworld-4x4", "--gamma", "2"], 2, ["--gamma must be in [0, 1]"]),
    (["show", "recycling-robot", "--max-rows", "-1"], 2, ["--max-rows must be"]),
    # problems and policies by name
    (["solve", "recycling-robt"], 2, ["unknown problem", "did you mean 'recycling-robot'"]),
    (["show", "no-such-problem"], 2, ["unknown problem 'no-such-problem'", "known problems"]),
    (["learn", "q-learning", "no-such-problem"], 2, ["unknown problem"]),
    (["solve", "NoSuchEnv-v0"], 2, ["unknown problem 'NoSuchEnv-v0'", "Gymnasium"]),
    (["solve", "CartPole-v1"], 2, ["no transition model `P`"]),
    (["evaluate", "recycling-robot", "--policy", "unifrm"], 2, ["did you mean 'uniform'"]),
    (["evaluate", "recycling-robot", "--policy", "/nonexistent/p.json"], 2, ["does not exist"]),
    (["plot", "values", "recycling-robot", "--policy", "nope"], 2, ["unknown policy 'nope'"]),
    (["learn", "mc-prediction", "blackjack", "--policy", "nope"], 2, ["unknown policy 'nope'"]),
    # options of single algorithms, checked by the learners before they run
    (["learn", "td-lambda", "random-walk", "--lambda", "2"], 2, ["lambda must be in [0, 1]"]),
    (["learn", "n-step-sarsa", "windy-gridworld", "--n", "0"], 2, ["n (the number of steps)"]),
    (["learn", "dyna-q", "windy-gridworld", "--planning-steps", "-1"], 2, ["planning_steps"]),
    (["learn", "sarsa-lambda", "windy-gridworld", "--trace", "foo"], 2, ["'accumulating'"]),
    ([*LEARN, "--epsilon", "-0.1"], 2, ["epsilon must stay in [0, 1]"]),
    (["learn", "mc-prediction", "recycling-robot"], 2, ["Monte Carlo needs an episodic task"]),
    (["learn", "q-learning", "CartPole-v1"], 2, ["tabular learners need discrete"]),
    (["solve", "recycling-robot", "--method", "lp", "--gamma", "1"], 2, ["no terminal state"]),
    # deep RL: train, eval, record ({run}: a finished tiny PPO run, {file}: a plain file,
    # {junk}: a folder whose checkpoint.pt is random bytes, {tmp}: a fresh empty folder)
    # counts and seeds
    ([*TRAIN, "--steps", "0"], 2, ["--steps", "positive integer", "got 0"]),
    ([*TRAIN, "--steps", "-5", "--dry-run"], 2, ["--steps", "got -5"]),
    ([*TRAIN, "--eval-episodes", "-1"], 2, ["--eval-episodes", ">= 0", "got -1"]),
    ([*TRAIN, "--seed", "-1"], 2, ["--seed", "non-negative", "got -1"]),
    (["eval", "{run}", "--episodes", "0"], 2, ["--episodes", "positive integer"]),
    (["eval", "{run}", "--seed", "-3"], 2, ["--seed", "got -3"]),
    (["record", "{run}", "--fps", "0"], 2, ["--fps", "positive integer"]),
    (["record", "{run}", "--every", "0"], 2, ["--every", "positive integer"]),
    (["record", "{run}", "--max-steps", "-1"], 2, ["--max-steps", "got -1"]),
    # the config, validated in --dry-run as in a real run
    ([*TRAIN, "--set", "activation=sigmoidz", "--dry-run"], 2, ["activation", "'sigmoidz'"]),
    ([*TRAIN, "--set", "n_steps=0", "--dry-run"], 2, ["n_steps", ">= 1"]),
    ([*TRAIN, "--set", "gamma=2", "--dry-run"], 2, ["gamma", "[0, 1]", "2.0"]),
    ([*TRAIN, "--set", "nosuch=1", "--dry-run"], 2, ["unknown PPOConfig field", "'nosuch'"]),
    ([*TRAIN, "--set", "n_envs=x", "--dry-run"], 2, ["'n_envs'", "integer", "'x'"]),
    ([*TRAIN, "--set", "oops"], 2, ["--set takes FIELD=VALUE", "'oops'"]),
    ([*TRAIN, "--config", "{tmp}/none.toml"], 2, ["config file", "does not exist"]),
    # names
    (["train", "a2c", "CartPole-v1"], 2, ["unknown algorithm", "'a2c'", "dqn, ppo"]),
    (["train", "ppo", "NoSuchEnv-v0", "--steps", "10"], 2, ["NoSuchEnv-v0"]),
    pytest.param(
        ["train", "ppo", "LunarLander-v3", "--steps", "10", "--out", "{tmp}/ll"],
        2,
        ["LunarLander-v3", "Box2D", "pip install 'policylab[box2d]'"],
        marks=pytest.mark.skipif(_BOX2D, reason="Box2D is installed here"),
    ),  # type: ignore[list-item]
    # output paths, checked before any work
    ([*TRAIN, "--out", "{file}"], 2, ["--out", "is an existing file"]),
    ([*TRAIN, "--out", "/proc/nope/run"], 2, ["--out", "/proc/nope/run", "cannot be written"]),
    (["record", "{tmp}/norun", "--out", "/proc/nope/x.gif"], 2, ["/proc/nope/x.gif", "cannot"]),
    (["record", "{run}", "--out", "{tmp}/x.bmp"], 2, ["suffix '.bmp'", ".gif, .png, .webp"]),
    (["record", "{run}", "--out", "{tmp}"], 2, ["--out", "suffix '(none)'"]),
    # checkpoints
    (["eval", "{junk}"], 2, ["not a policylab checkpoint (corrupt or foreign)"]),
    (["eval", "{tmp}/none"], 2, ["no checkpoint"]),
    (["record", "{junk}"], 2, ["not a policylab checkpoint (corrupt or foreign)"]),
    # run folders
    ([*TRAIN, "--out", "{tmp}/fresh", "--resume"], 2, ["holds no run to resume"]),
    ([*TRAIN, "--out", "{run}", "--steps", "64"], 2, ["already holds a run", "--resume"]),
    ([*TRAIN, "--out", "{run}", "--resume", "--set", "gamma=0.5"], 2, ["--set gamma", "resumed"]),
    ([*TRAIN, "--out", "{run}", "--resume", "--steps", "10"], 2, ["--steps 10", "below the"]),
    ([*TRAIN, "--out", "{run}", "--resume", "--seed", "5"], 2, ["--seed 5", "run's seed 0"]),
    (["train", "dqn", "CartPole-v1", "--out", "{run}", "--resume"], 2, ["is a ppo run"]),
]


def _case_id(case: object) -> str:
    argv = case.values[0] if hasattr(case, "values") else case[0]  # type: ignore[index]
    return " ".join(argv)


@pytest.fixture(scope="module")
def places(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("deep-bad-input")
    run = root / "run"
    try:
        main([*TRAIN, "--steps", "64", "--out", str(run), "--no-progress", "--eval-episodes",
              "0", "--set", "n_envs=2", "--set", "n_steps=32", "--set", "hidden=[8]"])  # fmt: skip
    except SystemExit as e:
        assert not e.code
    (root / "file").write_text("not a folder")
    (root / "junk").mkdir()
    (root / "junk" / "checkpoint.pt").write_bytes(bytes(range(256)) * 20)
    return {"run": str(run), "file": str(root / "file"), "junk": str(root / "junk")}


@pytest.mark.parametrize(("argv", "code", "words"), CASES, ids=[_case_id(c) for c in CASES])
def test_bad_input_exits_with_one_line(
    argv: list[str],
    code: int,
    words: list[str],
    run_cli: RunCLI,
    places: dict[str, str],
    tmp_path: Path,
) -> None:
    args = [a.format(tmp=tmp_path, **places) for a in argv]
    got, out, err = run_cli(args)
    assert got == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("policylab: error: "), err
    assert "Traceback" not in err and "np.float64(" not in err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert out == ""  # nothing was computed, nothing printed
    assert not any(tmp_path.iterdir())  # nothing was written


@pytest.mark.parametrize(
    "argv",
    [
        [*LEARN, "--seed", "-1"],
        ["learn", "q-lerning", "recycling-robot"],
        [*SOLVE, "--bogus"],
    ],
)
def test_the_entry_point_gives_the_same_one_line(argv: list[str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "policylab", *argv], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith("policylab: error: ")


def test_outputs_are_refused_before_any_learning(
    monkeypatch: pytest.MonkeyPatch, run_cli: RunCLI
) -> None:
    from policylab.tabular.registry import algorithm

    spec = algorithm("q-learning")

    def learner(*args: object, **kwargs: object) -> None:
        raise AssertionError("the learner ran before the output was checked")

    monkeypatch.setitem(spec.__dict__, "learner", learner)
    code, _, err = run_cli([*LEARN, "--plot", "out.xyz"])
    assert code == 2 and "'.xyz'" in err
    code, _, err = run_cli([*LEARN, "--plot", "/proc/nope/x.png"])
    assert code == 2 and "cannot be written" in err


def test_solve_refuses_its_figure_path_before_solving(
    monkeypatch: pytest.MonkeyPatch, run_cli: RunCLI
) -> None:
    import policylab.planning

    def solver(*args: object, **kwargs: object) -> None:
        raise AssertionError("solved before the output was checked")

    monkeypatch.setattr(policylab.planning, "policy_iteration", solver)
    code, _, err = run_cli([*SOLVE, "--plot", "/proc/nope/x.png"])
    assert code == 2 and "cannot be written" in err


def test_version_and_completion(run_cli: RunCLI) -> None:
    import policylab

    code, out, _ = run_cli(["--version"])
    assert code == 0 and out.strip() == f"policylab {policylab.__version__}"
    code, out, _ = run_cli(["--help"])
    assert code == 0 and "--install-completion" in out and "--version" in out


def test_help_shows_flags_without_a_bool_value(run_cli: RunCLI) -> None:
    for argv in (["solve", "--help"], ["learn", "q-learning", "--help"], ["problems", "--help"]):
        code, out, _ = run_cli(argv)
        assert code == 0 and "--json" in out
        assert "<bool>" not in out, argv
    code, out, _ = run_cli(["learn", "q-learning", "--help"])
    assert "design.md" not in out


@pytest.mark.parametrize("argv", [[], ["learn"], ["plot"]])
def test_no_arguments_show_the_help_and_no_empty_error(argv: list[str], run_cli: RunCLI) -> None:
    code, out, err = run_cli(argv)
    assert code == 2 and "Usage: policylab" in out and "error" not in err
