"""The tour's figures: each section draws what the section before it computed.

Every figure is written under the tour's ``out_dir`` (``runs/tour/`` by default) and
recorded with :meth:`TourContext.figure`, so the tour lists them at the end.
matplotlib is imported here only when the tour runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import policylab as pl
from policylab.cli.tour import TourContext, tour_section


def _save(ctx: TourContext, fig: Any, name: str) -> Path:
    from policylab.plot import save_figure

    path = save_figure(fig, ctx.out_dir / name)
    ctx.figure(path)
    return path


@tour_section(12, "Figures 1, 7: the interaction loop and one episode on the grid")
def loop_figures(ctx: TourContext) -> None:
    """The agent-environment loop, and the notes' sample episodes drawn on their grids."""
    from policylab.plot import episode_figure, interaction_loop_figure

    _save(ctx, interaction_loop_figure(), "loop.png")
    mdp = pl.problems.slippery_gridworld()
    ep = pl.rollout(mdp, pl.Policy.uniform(mdp), seed=ctx.seed)
    _save(ctx, episode_figure(mdp, ep, title="An episode of the random policy"), "episode.png")
    m = pl.problems.mountain_gridworld()
    bad = pl.rollout(m, pl.problems.mountain_gridworld_bad_policy(m), seed=ctx.seed)
    _save(ctx, episode_figure(m, bad, title="The bad policy's path: G_0 = -6"), "episode_bad.png")
    ctx.console.print(
        "Drawn: the loop S_t -> A_t -> R_{t+1}, S_{t+1}; an episode of the random policy on "
        "the slippery gridworld; the bad policy's path over the mountains (return -6)."
    )


@tour_section(47, "Figures: the recycling robot's values and policies")
def robot_figures(ctx: TourContext) -> None:
    """The values of the notes' stochastic policy, and v*, pi*, q* of the robot."""
    from policylab.plot import save_solution_figure

    mdp = pl.problems.recycling_robot()
    sto = pl.problems.recycling_robot_stochastic_policy(mdp)
    v = pl.evaluate_policy(mdp, sto)
    ctx.figure(
        save_solution_figure(
            mdp,
            v,
            sto,
            ctx.out_dir / "robot_stochastic.png",
            q=pl.action_values(mdp, v),
            title="Recycling robot: the notes' stochastic policy and its values (γ = 0.9)",
        )
    )
    res = pl.value_iteration(mdp)
    ctx.figure(
        save_solution_figure(
            mdp,
            res.v,
            res.policy,
            ctx.out_dir / "robot_optimal.png",
            q=res.q,
            title="Recycling robot: v*, π* and q* (γ = 0.9)",
        )
    )
    ctx.console.print(
        f"v*(high) = {res.v[0]:.3f}, v*(low) = {res.v[1]:.3f}: bars and tables drawn."
    )


@tour_section(52, "Figures 4, 5, 6: the mountain gridworld's bad and optimal policies")
def mountain_figures(ctx: TourContext) -> None:
    """Values in each cell, policies as arrows, action values as triangles."""
    from policylab.plot import save_solution_figure

    mdp = pl.problems.mountain_gridworld()
    bad = pl.problems.mountain_gridworld_bad_policy(mdp)
    v = pl.evaluate_policy(mdp, bad)
    ctx.figure(
        save_solution_figure(
            mdp,
            v,
            bad,
            ctx.out_dir / "mountain_bad.png",
            q=pl.action_values(mdp, v),
            title="The bad policy: v = -6 at the start, -5 to its right",
        )
    )
    res = pl.value_iteration(mdp)
    ctx.figure(
        save_solution_figure(
            mdp,
            res.v,
            res.policy,
            ctx.out_dir / "mountain_optimal.png",
            q=res.q,
            title=f"The optimal policy: v* = {res.v[mdp.state_index((2, 0))]:g} at the start",
        )
    )
    ctx.console.print("Each cell shows its value; arrows the policy; triangles q(s, a).")


@tour_section(62, "Figure 9: the Monte Carlo Q-table against the exact one")
def mc_q_table_figure(ctx: TourContext) -> None:
    """MC prediction of q_pi for the random policy, beside q_pi from a linear solve."""
    from policylab.plot import q_table_figure
    from policylab.tabular import mc_prediction

    mdp = pl.problems.slippery_gridworld()
    pi = pl.Policy.uniform(mdp)
    episodes = 2_000 if ctx.quick else 20_000
    res = mc_prediction(mdp, pi, episodes=episodes, seed=ctx.seed, progress=False)
    q_pi = pl.action_values(mdp, pl.evaluate_policy(mdp, pi))
    fig = q_table_figure(
        mdp,
        res.q,
        reference=q_pi,
        labels=(f"Monte Carlo, {episodes:,} episodes", "exact q_π"),
        title="The Q-table of the random policy (notes' figure 9)",
    )
    _save(ctx, fig, "slippery_q_table.png")
    live = mdp.action_mask
    ctx.console.print(
        f"max |Q - q_pi| = {np.max(np.abs(res.q - q_pi)[live]):.3f} after {episodes:,} episodes."
    )


@tour_section(72, "Figures: TD control on FrozenLake, over seeds")
def td_figures(ctx: TourContext) -> None:
    """Q-learning and Sarsa learning curves (mean and bootstrap band), and Q-learning's Q."""
    from policylab import tabular
    from policylab.plot import save_learning_figure, save_solution_figure

    mdp = pl.FiniteMDP.from_gymnasium("FrozenLake-v1", gamma=0.95)
    episodes = 2_000 if ctx.quick else 10_000
    seeds = 3 if ctx.quick else 5
    opts: dict[str, Any] = {
        "episodes": episodes,
        "alpha": "inverse:1,0.6,0",
        "epsilon": "exp:1,0.999,0.01",
        "checkpoints": 20,
        "progress": False,
    }
    runs = {
        name: [getattr(tabular, fn)(mdp, seed=ctx.seed + k, **opts) for k in range(seeds)]
        for name, fn in (("Q-learning", "q_learning"), ("Sarsa", "sarsa"))
    }
    ctx.figure(
        save_learning_figure(
            runs,
            ctx.out_dir / "frozenlake_learning.png",
            title=f"FrozenLake-v1 (γ = 0.95): TD control over {seeds} seeds",
        )
    )
    last = runs["Q-learning"][0]
    pi = last.to_policy()
    ctx.figure(
        save_solution_figure(
            mdp,
            pl.evaluate_policy(mdp, pi),
            pi,
            ctx.out_dir / "frozenlake_q_learning.png",
            q=last.q,
            title="FrozenLake: Q-learning's greedy policy, its exact value and Q",
        )
    )
    ctx.console.print(
        "Mean over seeds with a 95% bootstrap band; the error is measured against q* "
        "(value iteration)."
    )


@tour_section(90, "Figures from the book: 3.5, 4.2, 4.3, 5.2")
def textbook_figures(ctx: TourContext) -> None:
    """Optimal solutions of Sutton & Barto's examples, in the book's layouts."""
    from policylab.plot import save_solution_figure

    names = ["gridworld-5x5", "gamblers-problem"]
    if not ctx.quick:
        names += ["jacks-car-rental", "blackjack", "cliff-walking", "windy-gridworld"]
    for name in names:
        mdp = pl.problems.get_problem(name)
        res = pl.value_iteration(mdp)
        ctx.figure(
            save_solution_figure(mdp, res.v, res.policy, ctx.out_dir / f"{name}.png", q=res.q)
        )
    ctx.console.print(f"Optimal values and policies drawn for {', '.join(names)}.")
