"""The tour's sections on the notes' sections 4 (the problem) and 5 (policies)."""

from __future__ import annotations

import numpy as np
from rich.table import Table

import policylab as pl
from policylab.cli.tour import TourContext, tour_section


@tour_section(10, "4. The agent-environment loop and returns")
def loop_and_returns(ctx: TourContext) -> None:
    """An episode S0, A0, R1, ... of the equiprobable policy, and its discounted returns."""
    c = ctx.console
    mdp = pl.problems.slippery_gridworld()
    ep = pl.rollout(mdp, pl.Policy.uniform(mdp), seed=ctx.seed)
    c.print("The agent observes S_t, picks A_t, and the environment answers R_{t+1}, S_{t+1}.")
    c.print(f"One episode of the random policy on the slippery gridworld ({len(ep)} steps):")
    c.print(f"  {ep}", soft_wrap=True)
    table = Table(title="Returns of that episode, G_t = R_{t+1} + gamma G_{t+1}")
    table.add_column("gamma")
    table.add_column("G_0", justify="right")
    for g in (1.0, 0.9, 0.5, 0.0):
        table.add_row(f"{g:g}", f"{ep.ret(g):.4f}")
    c.print(table)
    c.print("gamma = 0 keeps only R_1; gamma = 1 weighs every reward the same.")
    from policylab.plot import episode_figure, interaction_loop_figure

    ctx.save(interaction_loop_figure(), "01_interaction_loop.png")
    ctx.save(
        episode_figure(mdp, ep, gamma=1.0, title="One episode of the random policy (notes fig. 7)"),
        "02_slippery_episode.png",
    )
    c.print(
        "The walking robot's per-step reward (notes 4.1): "
        "r = min(v_x, v_max) - 0.005 (v_y^2 + v_z^2) - 0.05 y^2 - 0.02 ||u||^2 + 0.02"
    )


@tour_section(20, "4.3 The recycling robot as a finite MDP")
def recycling_robot(ctx: TourContext) -> None:
    """The robot's one-step dynamics p(s', r | s, a) and its two example policies."""
    c = ctx.console
    mdp = pl.problems.recycling_robot()
    table = Table(title="p(s', r | s, a) of the recycling robot (alpha 0.7, beta 0.2)")
    for col in ("s", "a", "s'", "r", "p"):
        table.add_column(col)
    for s in mdp.states:
        for a in mdp.available_actions(s):
            for p, n, r in mdp.outcomes(s, a):
                table.add_row(str(s), str(a), str(n), f"{r:g}", f"{p:g}")
    c.print(table)
    c.print(f"A(high) = {mdp.available_actions('high')}, A(low) = {mdp.available_actions('low')}")
    c.print(
        f"p(high, 4 | high, search) = {mdp.p('high', 4.0, 'high', 'search'):g} (the notes' example)"
    )
    det = pl.problems.recycling_robot_deterministic_policy(mdp)
    sto = pl.problems.recycling_robot_stochastic_policy(mdp)
    c.print(f"deterministic policy: {det.to_dict()}")
    c.print(f"stochastic policy:    {sto.to_dict()}")
    steps = 200 if ctx.quick else 2000
    rng = np.random.default_rng(ctx.seed)
    for name, pi in (("deterministic", det), ("stochastic", sto)):
        ep = pl.rollout(mdp, pi, seed=rng, max_steps=steps)
        c.print(
            f"  {name}: {steps} steps of the continuing task, mean reward per step "
            f"{ep.rewards.mean():.3f}, discounted return G_0 (gamma 0.9) {ep.ret(0.9):.3f}"
        )


@tour_section(30, "5. Policies on the mountain gridworld")
def mountain_bad_policy(ctx: TourContext) -> None:
    """The notes' bad policy: the return from the start is -6, from the cell right of it -5."""
    c = ctx.console
    mdp = pl.problems.mountain_gridworld()
    pi = pl.problems.mountain_gridworld_bad_policy(mdp)
    for start in ((2, 0), (2, 1)):
        ep = pl.rollout(mdp, pi, seed=ctx.seed, start=start)
        c.print(f"from {start}: {ep}", soft_wrap=True)
        c.print(f"  return (gamma = 1) = {ep.ret(1.0):g}")
    c.print("The notes: -6 from the start, -5 from the cell to its right.")
    from policylab.plot import episode_figure

    ep = pl.rollout(mdp, pi, seed=ctx.seed, start=(2, 0))
    ctx.save(
        episode_figure(mdp, ep, gamma=1.0, title="The notes' bad policy from the start: G = -6"),
        "03_mountain_bad_policy_episode.png",
    )
