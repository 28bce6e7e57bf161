"""AlphaZero on tic-tac-toe: train with the defaults, then check it against perfect play.

The check is exhaustive: every line of play of the perfect player (each of its optimal
moves at every turn) and of any opponent at all (every legal move), with the trained
network moving first and second; a result of 0 means it never loses.

Run: ``python benchmarks/bench_alphazero.py [RUN_DIR]`` (trains into RUN_DIR, default
``runs/bench-alphazero-ttt``, unless it already holds a finished run).

The Connect Four run of the issue (about 2 hours on this machine) is not run here; its
command is ``policylab train alphazero connect-four --out runs/az-c4`` followed by
``policylab arena connect-four runs/az-c4 mcts:100 --games 100`` and ``... mcts:1000``.
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


def main() -> None:
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
        f"{doc['config']['simulations']} PUCT simulations per move; {how}). "
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
