"""The tour's sections on temporal-difference learning (Sutton & Barto chapter 6)."""

from __future__ import annotations

import numpy as np
from rich.table import Table

import policylab as pl
from policylab.cli.tour import TourContext, tour_section

#: FrozenLake's actions (0 left, 1 down, 2 right, 3 up) as arrows.
_ARROWS = ("<", "v", ">", "^")


@tour_section(70, "TD control: Q-learning on FrozenLake-v1 against its exact optimum")
def q_learning_frozenlake(ctx: TourContext) -> None:
    """Q-learning with decaying schedules on slippery FrozenLake 4x4, held against q*."""
    from policylab import tabular
    from policylab.planning import evaluate_policy, value_iteration

    c = ctx.console
    mdp = pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=0.95)
    episodes = 10_000 if ctx.quick else 30_000
    res = tabular.q_learning(
        mdp,
        episodes=episodes,
        alpha="inverse:1,0.6,0",
        epsilon="exp:1,0.9995,0.01",
        seed=ctx.seed,
        checkpoints=8,
    )
    c.print(
        "Q(S, A) <- Q(S, A) + alpha [R + gamma max_a Q(S', a) - Q(S, A)], on Gymnasium's "
        "slippery FrozenLake (gamma 0.95), alpha = 1/n^0.6 per pair, epsilon decaying "
        f"from 1 to 0.01: {res.steps:,} steps in {res.seconds:.2f} s (compiled kernel)."
    )
    table = Table(title="Error against q* (value iteration) as learning goes on")
    for col in ("episodes", "max |Q - q*|", "RMS", "greedy action optimal"):
        table.add_column(col, justify="right")
    for k, e_max, e_rms, share in zip(
        res.checkpoints, res.error_max, res.error_rms, res.optimal_actions, strict=True
    ):
        table.add_row(f"{k:,}", f"{e_max:.3f}", f"{e_rms:.3f}", f"{share:.0%}")
    c.print(table)
    v_star = value_iteration(mdp, tol=1e-12).v
    v_learned = evaluate_policy(mdp, res.to_policy())
    greedy = np.argmax(res.policy, axis=1)
    rows = []
    for r in range(4):
        cells = []
        for j in range(4):
            s = 4 * r + j
            cells.append(
                "H" if mdp.terminal[s] and s != 15 else "G" if s == 15 else _ARROWS[greedy[s]]
            )
        rows.append(" ".join(cells))
    c.print("Greedy policy of the learned Q (H hole, G goal):")
    for line in rows:
        c.print(f"  {line}")
    c.print(
        f"Value of the start state (gamma 0.95): learned greedy policy {v_learned[0]:.4f}, "
        f"exact optimum v*(start) = {v_star[0]:.4f}."
    )


@tour_section(71, "TD control: Sarsa and Q-learning on the cliff (Example 6.6)")
def cliff_walking(ctx: TourContext) -> None:
    """Figure 6.4's numbers: many seeds at once, Sarsa's safe path against Q-learning's."""
    from policylab import tabular

    c = ctx.console
    mdp = pl.problems.cliff_walking()
    seeds = 20 if ctx.quick else 100
    table = Table(title=f"Cliff walking, epsilon 0.1, alpha 0.5, {seeds} seeds x 500 episodes")
    table.add_column("algorithm")
    table.add_column("mean reward / episode (101-500)", justify="right")
    table.add_column("book (Figure 6.4)", justify="right")
    table.add_column("seconds", justify="right")
    for name, book in (
        ("sarsa", "about -29"),
        ("q-learning", "about -50"),
        ("expected-sarsa", "above Sarsa"),
    ):
        study = tabular.seed_study(
            name, mdp, seeds, seed=ctx.seed, episodes=500, alpha=0.5, epsilon=0.1
        )
        table.add_row(name, f"{study.mean_return(100):.1f}", book, f"{study.seconds:.2f}")
    c.print(table)
    c.print(
        "Q-learning learns the optimal path along the edge (-13) but its exploring steps "
        "fall off the cliff; Sarsa learns the longer, safer path its own exploration needs."
    )
