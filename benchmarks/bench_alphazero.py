"""AlphaZero on tic-tac-toe: train with the defaults, then check it against perfect play.

The check is exhaustive: every line of play of the perfect player (each of its optimal
moves at every turn) and of any opponent at all (every legal move), with the trained
network moving first and second; a result of 0 means it never loses.

Run: ``python benchmarks/bench_alphazero.py [RUN_DIR]`` (trains into RUN_DIR, default
``runs/bench-alphazero-ttt``, unless it already holds a finished run).

Connect Four (a run of hours on a laptop CPU, so not run by ``make bench``): train with
``policylab train alphazero connect-four --out runs/az-c4``, then
``python benchmarks/bench_alphazero.py --connect-four runs/az-c4 [GAMES]`` plays GAMES
(default 100; fewer is a trial, not recorded) games each against UCT with 100 and 1000
simulations (colours alternating, AlphaZero's searches batched across the games) and
measures the share of its moves that the exact solver rates optimal, over a seeded
sample of 300 of its moves with 20 or more stones on the board in those games.
"""

from __future__ import annotations

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


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--connect-four":
        games = int(sys.argv[3]) if len(sys.argv) > 3 else 100
        connect_four(Path(sys.argv[2]), games)
        return
    run = Path(sys.argv[1] if len(sys.argv) > 1 else "runs/bench-alphazero-ttt")
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    cfg = default_config("tic-tac-toe")
    t0 = time.perf_counter()
    trained_here = not (run / "run.json").exists()
    if trained_here:
        train_alphazero("tic-tac-toe", run, cfg)
    seconds = time.perf_counter() - t0
    doc = json.loads((run / "run.json").read_text())
    player = make_player(str(run), TIC_TAC_TOE)
    rows = []
    for me, side in ((0, "first (X)"), (1, "second (O)")):
        vs_perfect = worst_outcome(player, TIC_TAC_TOE.initial(), me, best_moves)
        vs_any = worst_outcome(player, TIC_TAC_TOE.initial(), me, lambda s: s.legal_actions())
        rows.append(f"| {side} | {vs_perfect:+.0f} | {vs_any:+.0f} |")
        print(side, vs_perfect, vs_any, flush=True)
    res = arena(TIC_TAC_TOE, player, make_player("mcts:200", TIC_TAC_TOE, 0), 100)
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    how = f"trained here in {seconds / 60:.1f} min" if trained_here else "an existing run"
    body = (
        f"AlphaZero on tic-tac-toe with the default settings ({doc['config']['iterations']} "
        f"iterations of {doc['config']['games_per_iteration']} self-play games, "
        f"{doc['config']['simulations']} PUCT simulations per move, a new network kept when it "
        f"scores at least {doc['config']['accept_score']} against the best; {how}). "
        "Worst result over every line of play (exhaustive), -1 a loss, 0 a draw:\n\n"
        "| AlphaZero moves | against every line of perfect play | against every opponent |\n"
        "|---|---:|---:|\n" + "\n".join(rows) + "\n\n"
        f"Against UCT with 200 random-rollout simulations, 100 games, colours alternating: "
        f"{res.wins} wins, {res.draws} draws, {res.losses} losses.\n\n"
        f"Load (`uptime`) before: `{load}`; after: `{load_after}` (a shared 2-core machine)."
    )
    write_section("AlphaZero (tic-tac-toe)", "python benchmarks/bench_alphazero.py", body)
    print(body)


if __name__ == "__main__":
    main()
