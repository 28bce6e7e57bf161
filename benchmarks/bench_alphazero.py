"""AlphaZero on tic-tac-toe: train with the defaults, then check it against perfect play.

The check is exhaustive: every line of play of the perfect player (each of its optimal
moves at every turn) and of any opponent at all (every legal move), with the trained
network moving first and second; a result of 0 means it never loses.

Run: ``python benchmarks/bench_alphazero.py [--seeds 0,1,2,3,4] [--out DIR]`` (trains one
run per seed into DIR/seed-K, default ``runs/bench-alphazero-ttt``, unless it already
holds a finished run; ``--help`` lists the options).

Connect Four (a run of hours on a laptop CPU, so not run by ``make bench``): train with
``policylab train alphazero connect-four --out runs/az-c4``, then
``python benchmarks/bench_alphazero.py --connect-four runs/az-c4 [--games GAMES]`` plays GAMES
(default 100; fewer is a trial, not recorded) games each against UCT with 100 and 1000
simulations (colours alternating, AlphaZero's searches batched across the games) and
measures the share of its moves that the exact solver rates optimal, over a seeded
sample of 300 of its moves with 20 or more stones on the board in those games.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from policylab.games import TIC_TAC_TOE, arena, best_moves, make_player
from policylab.games.alphazero import default_config, train_alphazero
from policylab.games.arena import wilson_interval, worst_outcome

sys.path.insert(0, os.path.dirname(__file__))
from _report import write_section


def _against_mcts(run: Path, n: int, games: int) -> tuple[str, list[tuple[str, int]]]:
    """A table row of the run against mcts:n, and its moves with >= 20 stones on the board."""
    from policylab.games import CONNECT_FOUR
    from policylab.games.base import GameState

    player = make_player(str(run), CONNECT_FOUR)
    opponent = make_player(f"mcts:{n}", CONNECT_FOUR, n)
    ends: list[GameState] = []
    wins = draws = losses = 0
    for start in range(0, games, 20):  # 20 games side by side at a time; a tally after each
        res = arena(CONNECT_FOUR, player, opponent, min(20, games - start), finals=ends)
        wins, draws, losses = wins + res.wins, draws + res.draws, losses + res.losses
        print(f"mcts:{n} after {start + res.games} games: {wins}-{draws}-{losses}", flush=True)
    lo, hi = wilson_interval(wins, games)
    row = f"| mcts:{n} | {wins} | {draws} | {losses} | {wins / games:.0%} | [{lo:.0%}, {hi:.0%}] |"
    seen = []
    for i, end in enumerate(ends):
        me = i % 2  # AlphaZero moved first in the even games
        for k in range(20, len(end.moves)):
            if k % 2 == me:
                seen.append((end.position_string()[:k], end.moves[k]))
    print(row, flush=True)
    return row, seen


def connect_four(run: Path, games: int = 100, positions: int = 300) -> None:
    """Both opponents at once, one process each (the machine has two cores)."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    import numpy as np

    from policylab.games import CONNECT_FOUR, best_moves

    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    doc = json.loads((run / "run.json").read_text())
    t0 = time.perf_counter()
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        results = list(pool.map(_against_mcts, [run, run], [100, 1000], [games, games]))
    lines = [row for row, _ in results]
    seen = [x for _, moves in results for x in moves]
    print(f"games: {time.perf_counter() - t0:.0f} s", flush=True)
    rng = np.random.default_rng(7)
    pick = rng.permutation(len(seen))[:positions]
    good = sum(seen[j][1] in best_moves(CONNECT_FOUR.from_moves(seen[j][0])) for j in pick)
    total = len(pick)
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    cfg = doc["config"]
    body = (
        f"AlphaZero on Connect Four: run `{run}` after {doc['iteration']} iterations of "
        f"{cfg['games_per_iteration']} self-play games ({cfg['simulations']} PUCT simulations "
        f"per move, a {cfg['channels']}-channel network of {cfg['blocks']} residual blocks); "
        f"it plays with {cfg['eval_simulations']} simulations per move, no noise, its most "
        f"visited move. {games} games against each opponent, colours alternating:\n\n"
        "| opponent | wins | draws | losses | win rate | wins, 95% Wilson |\n"
        "|---|---:|---:|---:|---:|---|\n"
        + "\n".join(lines)
        + f"\n\nIts moves that the exact solver rates optimal: {good} of {total} "
        f"({good / max(total, 1):.0%}), a seeded sample of its moves with 20 or more stones "
        "on the board in the games above.\n\n"
        f"Load (`uptime`) before: `{load}`; after: `{load_after}`."
    )
    print(body)
    if games >= 100:
        write_section(
            "AlphaZero (Connect Four)",
            f"python benchmarks/bench_alphazero.py --connect-four {run}",
            body,
        )


def _tic_tac_toe_seed(run: Path, seed: int) -> tuple[str, bool, float]:
    """Train (unless ``run`` holds a finished run) and check one seed; a table row."""
    cfg = default_config("tic-tac-toe", seed=seed)
    t0 = time.perf_counter()
    if not (run / "run.json").exists():
        train_alphazero("tic-tac-toe", run, cfg)
    minutes = (time.perf_counter() - t0) / 60
    player = make_player(str(run), TIC_TAC_TOE)
    worst = []
    for me in (0, 1):
        worst.append(worst_outcome(player, TIC_TAC_TOE.initial(), me, best_moves))
        worst.append(worst_outcome(player, TIC_TAC_TOE.initial(), me, lambda s: s.legal_actions()))
    res = arena(TIC_TAC_TOE, player, make_player("mcts:200", TIC_TAC_TOE, 0), 100)
    cells = " | ".join(f"{w:+.0f}" for w in worst)
    row = f"| {seed} | {cells} | {res.wins}-{res.draws}-{res.losses} | {minutes:.1f} |"
    print(row, flush=True)
    return row, min(worst) >= 0, minutes


def tic_tac_toe(out: Path, seeds: list[int]) -> None:
    """AlphaZero's tic-tac-toe defaults over several seeds, each checked exhaustively."""
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    cfg = default_config("tic-tac-toe")
    results = [_tic_tac_toe_seed(out / f"seed-{seed}", seed) for seed in seeds]
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    never = sum(ok for _, ok, _ in results)
    body = (
        f"AlphaZero on tic-tac-toe with the default settings ({cfg.iterations} iterations of "
        f"{cfg.games_per_iteration} self-play games, {cfg.simulations} PUCT simulations per "
        f"move, a new network kept when it scores at least {cfg.accept_score} against the "
        f"best), one run per seed. Worst result over every line of play (exhaustive), -1 a "
        "loss, 0 a draw, of the perfect player (its optimal moves only) and of any opponent "
        "(every legal move), with AlphaZero moving first (X) and second (O); then 100 games "
        "against UCT with 200 random-rollout simulations, colours alternating "
        "(wins-draws-losses); training time in minutes of wall clock (0.0: an existing run "
        "was checked):\n\n"
        "| seed | X vs perfect | X vs any | O vs perfect | O vs any | vs UCT-200 | minutes |\n"
        "|---:|---:|---:|---:|---:|---|---:|\n"
        + "\n".join(row for row, _, _ in results)
        + f"\n\n{never} of {len(seeds)} seeds never lose with either colour. Training is "
        "deterministic on one machine (same seed, same network), but the network's "
        "floating-point rounding depends on the processor's matrix kernels, so a seed can "
        "end in a different network on another machine.\n\n"
        f"Load (`uptime`) before: `{load}`; after: `{load_after}` (a shared 2-core machine)."
    )
    command = "python benchmarks/bench_alphazero.py"
    if seeds != list(range(5)):
        command += f" --seeds {','.join(map(str, seeds))}"
    write_section("AlphaZero (tic-tac-toe)", command, body)
    print(body)


def main() -> None:
    parser = argparse.ArgumentParser(
        description="AlphaZero on tic-tac-toe (train with the defaults for each seed, then "
        "check each network exhaustively against perfect play and any opponent) or, with "
        "--connect-four RUN_DIR, an existing Connect Four run against UCT."
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("runs/bench-alphazero-ttt"),
        help="Folder of the tic-tac-toe runs, one subfolder per seed; a finished run there "
        "is checked, not trained again (default: runs/bench-alphazero-ttt).",
    )
    parser.add_argument(
        "--seeds",
        default="0,1,2,3,4",
        help="Comma-separated seeds of the tic-tac-toe runs (default: 0,1,2,3,4).",
    )
    parser.add_argument(
        "--connect-four",
        type=Path,
        metavar="RUN_DIR",
        help="Evaluate this Connect Four run instead (hours to train; not run by make bench).",
    )
    parser.add_argument(
        "--games",
        type=int,
        default=100,
        help="Connect Four games against each opponent (default 100; fewer is a trial, "
        "not recorded).",
    )
    args = parser.parse_args()
    if args.connect_four is not None:
        connect_four(args.connect_four, args.games)
        return
    try:
        seeds = [int(x) for x in args.seeds.split(",")]
    except ValueError:
        parser.error(f"--seeds must be comma-separated integers; got {args.seeds!r}")
    tic_tac_toe(args.out, seeds)


if __name__ == "__main__":
    main()
