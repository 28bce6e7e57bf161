"""AlphaZero on tic-tac-toe: train with the defaults, then check it against perfect play.

The check is exhaustive: every line of play of the perfect player (each of its optimal
moves at every turn) and of any opponent at all (every legal move), with the trained
network moving first and second; a result of 0 means it never loses.

Run: ``python benchmarks/bench_alphazero.py [RUN_DIR]`` (trains into RUN_DIR, default
``runs/bench-alphazero-ttt``, unless it already holds a finished run).

Connect Four (a run of hours on a laptop CPU, so not run by ``make bench``): train with
``policylab train alphazero connect-four --out runs/az-c4``, then
``python benchmarks/bench_alphazero.py --connect-four runs/az-c4`` plays 100 games each
against UCT with 100 and 1000 simulations (colours alternating) and measures the share
of its moves that the exact solver rates optimal, over 200 positions of sensible random
play with 14 to 30 stones.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from policylab.games import TIC_TAC_TOE, arena, make_player, solve_tic_tac_toe
from policylab.games.alphazero import default_config, train_alphazero
from policylab.games.arena import worst_outcome

sys.path.insert(0, os.path.dirname(__file__))
from _report import write_section


def connect_four(run: Path, games: int = 100, positions: int = 200) -> None:
    import numpy as np

    from bench_games import sensible_position
    from policylab.games import CONNECT_FOUR, connect_four_solver

    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    player = make_player(str(run), CONNECT_FOUR)
    lines = []
    for n in (100, 1000):
        res = arena(CONNECT_FOUR, player, make_player(f"mcts:{n}", CONNECT_FOUR, n), games)
        lo, hi = res.interval("wins")
        lines.append(
            f"| mcts:{n} | {res.wins} | {res.draws} | {res.losses} | [{lo:.0%}, {hi:.0%}] |"
        )
        print(lines[-1], flush=True)
    rng = np.random.default_rng(7)
    solver = connect_four_solver()
    good = total = 0
    while total < positions:
        s = sensible_position(int(rng.integers(14, 31)), rng)
        if s is None:
            continue
        total += 1
        good += player.choose(s) in solver.best_moves(s)
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    doc = json.loads((run / "run.json").read_text())
    body = (
        f"AlphaZero on Connect Four, run `{run}` ({doc['iteration']} iterations). {games} games "
        "against each opponent, colours alternating:\n\n"
        "| opponent | wins | draws | losses | wins, 95% Wilson |\n|---|---:|---:|---:|---|\n"
        + "\n".join(lines)
        + f"\n\nMoves the exact solver rates optimal: {good} of {total} "
        f"({good / total:.0%}) positions of sensible random play with 14 to 30 stones.\n\n"
        f"Load (`uptime`) before: `{load}`; after: `{load_after}`."
    )
    if games < 100:
        print(body)
        return  # a trial run, not a measurement
    write_section(
        "AlphaZero (Connect Four)",
        f"python benchmarks/bench_alphazero.py --connect-four {run}",
        body,
    )
    print(body)


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--connect-four":
        connect_four(Path(sys.argv[2]))
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
    sol = solve_tic_tac_toe()
    rows = []
    for me, side in ((0, "first (X)"), (1, "second (O)")):
        vs_perfect = worst_outcome(player, TIC_TAC_TOE.initial(), me, sol.best_moves)
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
