"""Bad input to the deep-RL commands (train, eval, record): one table, one test.

Each case is ``(argv, expected exit code, words expected in the one-line stderr)``.
``{tmp}`` in an argument is a fresh folder, ``{run}`` a finished tiny PPO run folder,
``{file}`` an existing plain file and ``{junk}`` a file of random bytes named
``checkpoint.pt``. Every case must fail before any training or rendering starts.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from policylab.cli.main import main

_BOX2D = importlib.util.find_spec("Box2D") is not None

TRAIN = ["train", "ppo", "CartPole-v1"]

CASES: list[tuple[list[str], int, list[str]]] = [
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


@pytest.mark.parametrize(("argv", "code", "words"), CASES)
def test_bad_input_exits_with_one_line(
    argv: list[str],
    code: int,
    words: list[str],
    places: dict[str, str],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    args = [a.format(tmp=tmp_path, **places) for a in argv]
    before = sorted(p.name for p in tmp_path.iterdir())
    try:
        main(args)
        got = 0
    except SystemExit as e:
        got = int(e.code or 0)
    out, err = capsys.readouterr()
    assert got == code, (args, out, err)
    assert err.endswith("\n") and err.count("\n") == 1, err  # exactly one line
    assert err.startswith("policylab: error: ") and "Traceback" not in err
    for w in words:
        assert w in err, (w, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing was written
