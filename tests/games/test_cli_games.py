"""The command line of the board games: solve, arena, play, train selfplay-td."""

from __future__ import annotations

import json

import pytest

from policylab.cli.main import main


def run(args, capsys, monkeypatch=None, stdin=None):
    if stdin is not None:
        import io

        monkeypatch.setattr("sys.stdin", io.StringIO(stdin))
    with pytest.raises(SystemExit) as exc:
        main([*args])
        raise SystemExit(0)
    out = capsys.readouterr()
    return exc.value.code or 0, out.out, out.err


def test_solve_tictactoe_json(capsys):
    code, out, _ = run(["solve", "tic-tac-toe", "--json"], capsys)
    assert code == 0 and json.loads(out) == {"value": 0, "best_moves": list(range(1, 10))}
    code, out, _ = run(["solve", "tic-tac-toe", "--position", "1", "--json"], capsys)
    assert json.loads(out) == {"value": 0, "best_moves": [5]}
    code, out, _ = run(["solve", "tic-tac-toe", "--position", "1527"], capsys)
    assert code == 0 and "best moves: [3]" in out


def test_solve_connect_four_json(capsys):
    # 30 stones; X wins with its 16th stone (22 - 16 = 6) only by column 2
    pos = "561644537123431111273563354727"
    code, out, _ = run(["solve", "connect-four", "--position", pos, "--json"], capsys)
    assert code == 0 and json.loads(out) == {"score": 6, "best_moves": [2]}


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["solve", "connect-four", "--position", "44x"], "character 3 is 'x'"),
        (["solve", "connect-four"], "needs --position"),
        (["solve", "connect-four", "--position", "1212121"], "is over"),
        (["solve", "tic-tac-toe", "--position", "11"], "illegal move 2"),
        (["arena", "tic-tac-toe", "random", "mcts:x"], "positive number of simulations"),
        (["arena", "tic-tac-toe", "random", "god"], "unknown player 'god'"),
        (["arena", "go", "random", "random"], "unknown game 'go'"),
        (["arena", "tic-tac-toe", "random", "random", "--games", "0"], "--games"),
        (["train", "selfplay-td", "connect-four", "--out", "/nonexistent/x"], "learns tic-tac-toe"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, args, message):
    code, out, err = run(args, capsys)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


def test_arena_json(capsys):
    code, out, _ = run(
        ["arena", "tic-tac-toe", "perfect", "random", "--games", "12", "--json"], capsys
    )
    data = json.loads(out)
    assert code == 0 and data["games"] == 12 and data["losses"] == 0
    assert data["wins"] + data["draws"] == 12
    code, out, _ = run(["arena", "connect-four", "mcts:50", "random", "--games", "2"], capsys)
    assert code == 0 and "95% interval" in out


def test_play_from_stdin(capsys, monkeypatch):
    # the person plays X: 1, 2, 3 against random, which cannot stop a win at 3? It can; so
    # play against perfect, which always draws or wins: the game must end properly
    code, out, _ = run(
        ["play", "tic-tac-toe", "--against", "perfect"],
        capsys,
        monkeypatch,
        stdin="5\n1\n9\nx\n3\n4\n6\n7\n8\n2\n",
    )
    assert code == 0 and ("a draw" in out or "you lose" in out)
    assert "'x' is not a legal move" in out
    code, out, _ = run(["play", "tic-tac-toe", "--second"], capsys, monkeypatch, stdin="")
    assert code == 0 and "abandoned" in out


def test_train_selfplay_td_cli(tmp_path, capsys):
    out_dir = tmp_path / "td"
    args = ["train", "selfplay-td", "tic-tac-toe", "--out", str(out_dir), "--no-progress"]
    code, out, _ = run([*args, "--set", "episodes=2000", "--set", "chunks=2"], capsys)
    assert code == 0 and (out_dir / "checkpoint.pt").is_file()
    assert json.loads((out_dir / "run.json").read_text())["episodes_done"] == 2000
    code, _, err = run(args, capsys)
    assert code == 2 and "already holds a run" in err
    code, _, err = run([*args[:-2], str(tmp_path / "new"), "--set", "gamma=1"], capsys)
    assert code == 2 and "unknown selfplay-td setting" in err
    code, out, _ = run(
        ["arena", "tic-tac-toe", str(out_dir), "random", "--games", "4", "--json"], capsys
    )
    assert code == 0 and json.loads(out)["games"] == 4
