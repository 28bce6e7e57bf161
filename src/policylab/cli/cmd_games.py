"""``policylab arena`` and ``policylab play``, and the board-game branches of ``solve``/``train``.

``solve tic-tac-toe|connect-four`` and ``train selfplay-td|alphazero GAME`` reach
:func:`solve_game` and :func:`train_game` from the ``solve`` and ``train`` commands.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from policylab.cli.common import console, print_json
from policylab.exceptions import InvalidArgumentError, TrainingInterrupted

if TYPE_CHECKING:
    from policylab.runs import RunFolder

__all__ = ["GAME_LEARNERS", "register", "solve_game", "train_game"]

GAME_LEARNERS = ("selfplay-td", "alphazero")


GameArg = Annotated[str, typer.Argument(help="The game: tic-tac-toe or connect-four.")]


def arena_command(
    game: GameArg,
    a: Annotated[str, typer.Argument(help="Player A (the results are from A's view).")],
    b: Annotated[str, typer.Argument(help="Player B.")],
    games: Annotated[int, typer.Option("--games", help="Games to play; colours alternate.")] = 100,
    seed: Annotated[int, typer.Option("--seed", help="Seed of both players.")] = 0,
    json_out: Annotated[
        bool, typer.Option("--json", help='Print {"wins", "draws", "losses", "games"}.')
    ] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Show a progress bar.")
    ] = True,
) -> None:
    """Play games between two players, colours alternating; wins, draws, losses from A's view.

    Players: random, perfect, mcts:N (UCT with N random-rollout simulations), or a
    run folder of `policylab train selfplay-td|alphazero GAME`.
    """
    import numpy as np
    from rich.progress import Progress

    from policylab.games.arena import arena
    from policylab.games.players import make_player
    from policylab.games.registry import get_game

    g = get_game(game)
    if games < 1:
        raise InvalidArgumentError(f"--games must be a positive integer; got {games}")
    seeds = np.random.SeedSequence(seed).spawn(2)
    pa = make_player(a, g, np.random.default_rng(seeds[0]))
    pb = make_player(b, g, np.random.default_rng(seeds[1]))
    t0 = time.perf_counter()
    if progress and not json_out:
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task(f"{pa.name} vs {pb.name}", total=games)
            res = arena(g, pa, pb, games, on_game=lambda _: bar.advance(task))
    else:
        res = arena(g, pa, pb, games)
    if json_out:
        print_json(res.to_json())
        return
    table = Table(title=f"{g.name}: {pa.name} (A) vs {pb.name} (B), {res.games} games")
    table.add_column("A's result")
    table.add_column("games", justify="right")
    table.add_column("share", justify="right")
    table.add_column("95% interval (Wilson)", justify="right")
    for what in ("wins", "draws", "losses"):
        k = getattr(res, what)
        lo, hi = res.interval(what)
        table.add_row(what, str(k), f"{k / res.games:.1%}", f"[{lo:.1%}, {hi:.1%}]")
    table.caption = (
        f"A moved first in {(res.games + 1) // 2} games; {time.perf_counter() - t0:.1f} s"
    )
    console.print(table)


def play_command(
    game: GameArg,
    against: Annotated[
        str | None,
        typer.Option(
            "--against",
            help="Your opponent (see arena); default perfect on tic-tac-toe, mcts:2000 on "
            "connect-four (the solver is slow in the opening).",
        ),
    ] = None,
    second: Annotated[bool, typer.Option("--second", help="Let the opponent move first.")] = False,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the opponent.")] = 0,
) -> None:
    """Play a game in the terminal: type the number of a cell (1-9) or column (1-7)."""
    from policylab.games.players import make_player
    from policylab.games.registry import get_game

    g = get_game(game)
    spec = against or ("perfect" if g.name == "tic-tac-toe" else "mcts:2000")
    opponent = make_player(spec, g, seed)
    me = 1 if second else 0
    s = g.initial()
    names = g.player_names
    console.print(f"{g.name}: you are {names[me]}, {opponent.name} is {names[1 - me]}")
    while not s.is_terminal():
        if s.player != me:
            a = opponent.choose(s)
            console.print(f"{opponent.name} plays {a + 1}")
            s = s.play(a)
            continue
        console.print(str(s))
        legal = s.legal_actions()
        console.print(f"your move ({', '.join(str(x + 1) for x in legal)}): ", end="")
        line = sys.stdin.readline()
        if not line:
            console.print("\nno more input; game abandoned")
            raise typer.Exit(0)
        text = line.strip()
        if text.lower() in ("q", "quit", "exit"):
            raise typer.Exit(0)
        if not text.isdigit() or int(text) - 1 not in legal:
            console.print(f"[red]{text!r} is not a legal move[/]")
            continue
        s = s.play(int(text) - 1)
    console.print(str(s))
    r = s.outcome(me)
    console.print("you win" if r > 0 else ("you lose" if r < 0 else "a draw"))


def solve_game(game: str, position: str | None, json_out: bool) -> None:
    """``policylab solve tic-tac-toe|connect-four [--position MOVES]``."""
    from policylab.games.registry import get_game
    from policylab.games.solvers import connect_four_solver, solve_tic_tac_toe

    g = get_game(game)
    if g.name == "connect-four" and position is None:
        raise InvalidArgumentError(
            "solve connect-four needs --position MOVES (columns 1-7, e.g. 4455); the empty "
            "board is a first-player win with the last stone (score 1) but takes long to solve"
        )
    s = g.from_moves(position or "")
    t0 = time.perf_counter()
    if g.name == "tic-tac-toe":
        sol = solve_tic_tac_toe()
        value = sol.value(s)  # type: ignore[arg-type]
        best = [] if s.is_terminal() else [a + 1 for a in sol.best_moves(s)]  # type: ignore[arg-type]
        move_values: dict[int, Any] = {} if s.is_terminal() else sol.move_values(s)  # type: ignore[arg-type]
        key = "value"
    else:
        solver = connect_four_solver()
        move_values = solver.move_scores(s)  # type: ignore[arg-type]
        value = max(move_values.values())
        top = value
        best = [a + 1 for a, v in move_values.items() if v == top]
        key = "score"
    seconds = time.perf_counter() - t0
    if json_out:
        print_json({key: value, "best_moves": best})
        return
    console.print(str(s))
    console.print(f"position {s.position_string() or '(start)'!r}: {s.result_text()}")
    what = (
        "value for the player to move (+1 win, 0 draw, -1 loss)"
        if key == "value"
        else "score for the player to move (22 - k: a win with their k-th stone; <0 a loss)"
    )
    console.print(f"{what}: [bold]{value}[/]; best moves: {best}  ({seconds:.3g} s)")
    if move_values:
        table = Table(title="every legal move")
        table.add_column("move", justify="right")
        table.add_column(key, justify="right")
        for a, v in move_values.items():
            table.add_row(str(a + 1), str(v))
        console.print(table)


def train_game(
    algo: str,
    game: str,
    *,
    out: Path | None,
    seed: int | None,
    resume: bool,
    fields: dict[str, Any],
    progress: bool,
) -> None:
    """``policylab train selfplay-td|alphazero GAME --out DIR``.

    The run folder follows the rules of every ``train`` run (one process at a time, no
    silent reuse, Ctrl-C or SIGTERM saves and exits with code 130 or 143); the message
    of an interrupt counts self-play games (selfplay-td) or iterations (alphazero).
    """
    from policylab.games.registry import get_game
    from policylab.runs import RUN_MARKERS, RunFolder

    g = get_game(game)
    seed = 0 if seed is None else seed
    run_dir = out or Path("runs") / f"{algo}-{g.name}-s{seed}"
    run = RunFolder(
        run_dir, resume=resume, markers=RUN_MARKERS, command=f"policylab train {algo} {g.name}"
    )
    try:
        if algo == "selfplay-td":
            _train_td(g.name, run, seed, resume, fields, progress)
        else:
            from policylab.games.alphazero import train_alphazero_cli

            train_alphazero_cli(g, run, seed, resume, fields, progress, console)
    except TrainingInterrupted as e:
        what = "game" if algo == "selfplay-td" else "iteration"
        typer.echo(f"interrupted at {what} {e.step:,}; continue with --resume", err=True)
        sys.exit(128 + e.signal)  # 130 for Ctrl-C, 143 for SIGTERM (the shells' convention)


def _train_td(
    game: str, run: RunFolder, seed: int, resume: bool, fields: dict[str, Any], progress: bool
) -> None:
    import dataclasses

    from rich.progress import Progress

    from policylab.games.learned import train_selfplay_td
    from policylab.games.runs import game_run
    from policylab.games.selfplay_td import SelfPlayTDConfig

    if game != "tic-tac-toe":
        raise InvalidArgumentError(
            f"selfplay-td learns tic-tac-toe (a table of its 5,478 positions); got {game}"
        )
    known = {f.name for f in dataclasses.fields(SelfPlayTDConfig)} - {"seed"}
    bad = set(fields) - known
    if bad:
        raise InvalidArgumentError(
            f"unknown selfplay-td setting(s) {', '.join(sorted(bad))}; "
            f"known: {', '.join(sorted(known))}"
        )
    if resume and fields:
        raise InvalidArgumentError(
            "--resume continues a run with its own settings; --set cannot change them"
        )
    cfg = SelfPlayTDConfig(**{**fields, "seed": seed})
    cfg.validate()
    t0 = time.perf_counter()
    with (
        game_run(run, resume=resume, algo="selfplay-td", game=game),
        Progress(console=console, disable=not progress) as bar,
    ):
        task = bar.add_task("self-play TD", total=None)
        train_selfplay_td(
            run,
            cfg,
            resume=resume,
            on_chunk=lambda done, total: bar.update(task, completed=done, total=total),
        )
        episodes = run.read_json("run.json")["episodes_done"]
    console.print(
        f"selfplay-td on tic-tac-toe: {episodes:,} self-play games in all "
        f"({time.perf_counter() - t0:.1f} s); run folder {run.path} "
        f"(try `policylab arena tic-tac-toe {run.path} perfect`)"
    )


def register(app: typer.Typer) -> None:
    """Add ``arena`` and ``play`` to the ``policylab`` command."""
    app.command("arena")(arena_command)
    app.command("play")(play_command)
