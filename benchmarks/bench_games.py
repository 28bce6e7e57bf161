"""Board games: Connect Four solver speed by game stage, and UCT simulations per second.

* The exact Connect Four solver (compiled negamax, alpha-beta on null windows,
  transposition table, move ordering) on positions with 10, 20 and 30 stones. The
  positions come from seeded "sensible random" games: each move is uniform among
  the moves that neither win at once nor let the opponent win at once, and a
  position is kept only if the player to move cannot win at once (so no position
  is solved by a one-move check). Each position gets a fresh transposition table.
* UCT with random rollouts on Connect Four: simulations per second from the empty
  board and from a 10-stone position, policylab's ``UCT`` against OpenSpiel's C++
  ``MCTSBot`` with a ``RandomRolloutEvaluator`` (one rollout per leaf, the same
  exploration constant), in the same run, where the ``bench`` extra is installed.

Run: ``python benchmarks/bench_games.py`` (or ``make bench BENCH=games``);
``--uct`` prints the search speed table alone.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from policylab.games import CONNECT_FOUR, UCT, ConnectFourSolver
from policylab.games.connect_four import ConnectFourState

sys.path.insert(0, os.path.dirname(__file__))
from _report import load_note, write_section

POSITIONS = {30: 10, 20: 10, 10: 6}
C_UCT = 1.4


def _c4_position(moves: str) -> ConnectFourState:
    s = CONNECT_FOUR.from_moves(moves)
    assert isinstance(s, ConnectFourState)
    return s


def _wins_now(s: ConnectFourState) -> bool:
    return any(s.play(a).winner is not None for a in s.legal_actions())


def sensible_position(stones: int, rng: np.random.Generator) -> ConnectFourState | None:
    """A position after ``stones`` moves of sensible random play, or None if that failed."""
    s = CONNECT_FOUR.initial()
    while len(s.moves) < stones:
        safe = [
            a for a in s.legal_actions() if s.play(a).winner is None and not _wins_now(s.play(a))
        ]
        if not safe:
            return None
        s = s.play(int(rng.choice(safe)))
    return None if s.is_terminal() or _wins_now(s) else s


def solver_rows() -> list[str]:
    rng = np.random.default_rng(2026)
    ConnectFourSolver(table_size=1009).score(_c4_position("4455"))  # compile
    rows = []
    for stones, count in POSITIONS.items():
        times: list[float] = []
        nodes: list[int] = []
        scores: list[int] = []
        while len(times) < count:
            s = sensible_position(stones, rng)
            if s is None:
                continue
            solver = ConnectFourSolver()
            sc, dt, n = solver.timed_score(s)
            times.append(dt)
            nodes.append(n)
            scores.append(sc)
            print(
                f"  {stones} stones {s.position_string()}: score {sc}, {dt:.3f} s, {n:,} nodes",
                flush=True,
            )
        rows.append(
            f"| {stones} | {count} | {statistics.median(times):.4f} | {statistics.mean(times):.4f} "
            f"| {max(times):.4f} | {statistics.mean(nodes):,.0f} "
            f"| {sum(nodes) / max(sum(times), 1e-9):,.0f} | {min(scores)}..{max(scores)} |"
        )
    return rows


def _rates(search: Callable[[int], object], sims: int) -> tuple[float, float]:
    """Best of 3 searches: (simulations per CPU second, per wall-clock second)."""
    cpu = wall = 0.0
    for rep in range(3):
        c0, t0 = time.process_time(), time.perf_counter()
        search(rep)
        cpu = max(cpu, sims / max(time.process_time() - c0, 1e-9))
        wall = max(wall, sims / (time.perf_counter() - t0))
    return cpu, wall


def ours_sims_per_second(state: ConnectFourState, sims: int) -> tuple[float, float]:
    UCT(50, c=C_UCT, seed=0).choose(state)  # compile the search
    return _rates(lambda rep: UCT(sims, c=C_UCT, seed=rep).visit_counts(state), sims)


def openspiel_sims_per_second(moves: str, sims: int) -> tuple[float, float] | None:
    try:
        import pyspiel
    except ImportError:
        return None
    game = pyspiel.load_game("connect_four")

    def search(rep: int) -> None:
        state = game.new_initial_state()
        for ch in moves:
            state.apply_action(int(ch) - 1)
        evaluator = pyspiel.RandomRolloutEvaluator(1, rep)
        bot = pyspiel.MCTSBot(game, evaluator, C_UCT, sims, 1000, False, rep, False)
        bot.step(state)

    return _rates(search, sims)


def uct_rows(sims: int) -> list[str]:
    rows = []
    for label, moves in (("empty board", ""), ("10 stones (4453432253)", "4453432253")):
        ours = ours_sims_per_second(_c4_position(moves), sims)
        theirs = openspiel_sims_per_second(moves, sims)
        if theirs is None:
            rows.append(f"| {label} | {ours[0]:,.0f} | not installed | - | {ours[1]:,.0f} | - |")
        else:
            rows.append(
                f"| {label} | {ours[0]:,.0f} | {theirs[0]:,.0f} | {ours[0] / theirs[0]:.2f} "
                f"| {ours[1]:,.0f} | {theirs[1]:,.0f} |"
            )
        print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description="Connect Four: the exact solver's time by game stage and UCT's "
        "simulations per second against OpenSpiel's, written to BENCHMARKS.md."
    )
    parser.add_argument(
        "--uct",
        action="store_true",
        help="Print the UCT search speed table alone (not recorded in BENCHMARKS.md).",
    )
    if parser.parse_args().uct:
        uct_rows(5000)
        return
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    loads = [os.getloadavg()[0]]
    print("Connect Four solver:", flush=True)
    rows = solver_rows()
    sims = 5000
    mcts_rows = uct_rows(sims)
    load_after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    loads.append(os.getloadavg()[0])
    body = (
        "Exact Connect Four solver (Pascal Pons' score convention), positions from sensible "
        "random play (no move wins or loses at once; the player to move cannot win at once), "
        "a fresh 8M-entry transposition table per position, one core:\n\n"
        "| stones | positions | median s | mean s | max s | mean nodes | nodes/s | scores |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---|\n"
        + "\n".join(rows)
        + f"\n\nUCT with random rollouts on Connect Four, {sims} simulations per move, "
        f"exploration constant {C_UCT}, best of 3 searches, in the same process: policylab's "
        "`UCT` (the whole search compiled with numba: the tree in arrays, playouts on the "
        "bitboards) against OpenSpiel's C++ `MCTSBot` with a `RandomRolloutEvaluator` (one "
        "rollout per leaf). Simulations per CPU second (the process's own CPU time, which "
        "the load of other jobs does not inflate) and per wall-clock second:\n\n"
        "| position | policylab sims/CPU s | OpenSpiel C++ sims/CPU s | policylab / OpenSpiel "
        "| policylab sims/wall s | OpenSpiel sims/wall s |\n"
        "|---|---:|---:|---:|---:|---:|\n"
        + "\n".join(mcts_rows)
        + f"\n\nLoad (`uptime`) before: `{load}`; after: `{load_after}`. "
        + load_note(*loads)
        + " The two libraries in one table ran side by side."
    )
    write_section("Board games (Connect Four)", "python benchmarks/bench_games.py", body)
    print(body)


if __name__ == "__main__":
    main()
