"""The tour's section on the notes' section 6: Monte Carlo methods on the slippery grid."""

from __future__ import annotations

import numpy as np
from rich.table import Table

import policylab as pl
from policylab.cli.tour import TourContext, tour_section


@tour_section(60, "6. Monte Carlo prediction: the Q-table of the random policy")
def mc_prediction_grid(ctx: TourContext) -> None:
    """First-visit MC on the slippery 2 x 2 gridworld, held against the exact q_pi."""
    from policylab.tabular import mc_prediction

    c = ctx.console
    mdp = pl.problems.slippery_gridworld()
    pi = pl.Policy.uniform(mdp)
    episodes = 2_000 if ctx.quick else 50_000
    res = mc_prediction(mdp, pi, episodes=episodes, seed=ctx.seed)
    v_pi = pl.evaluate_policy(mdp, pi)
    q_pi = pl.action_values(mdp, v_pi)
    c.print(
        f"{episodes} episodes of the equiprobable random policy from cell 1 "
        f"({res.steps} steps, {res.seconds:.2f} s). For every (state, action) the Q-table "
        "keeps the average of the returns that followed its first visit in each episode."
    )
    table = Table(title="Q-table: Monte Carlo estimate (exact q_pi)")
    table.add_column("state", style="bold")
    for a in mdp.actions:
        table.add_column(str(a), justify="right")
    table.add_column("visits", justify="right")
    for s, lab in enumerate(mdp.states):
        if mdp.terminal[s]:
            continue
        cells = [f"{res.q[s, a]:7.3f} ({q_pi[s, a]:.3f})" for a in range(mdp.n_actions)]
        table.add_row(str(lab), *cells, str(int(res.counts[s].sum())))
    c.print(table)
    curve = Table(title="The error falls with the number of episodes (about 1/sqrt(n))")
    for col in ("episodes", "max |Q - q_pi|", "RMS error"):
        curve.add_column(col, justify="right")
    n = len(res.checkpoints)
    for i in sorted(set(np.linspace(0, n - 1, 8).round().astype(int))):
        curve.add_row(str(res.checkpoints[i]), f"{res.error_max[i]:.3f}", f"{res.error_rms[i]:.3f}")
    c.print(curve)
    greedy = res.to_policy()
    exact = pl.greedy_policy(mdp, q_pi)
    c.print(
        "The notes' last step, a greedy policy from the Q-table: "
        + ", ".join(f"{s} -> {greedy(s)}" for s in mdp.states if s != 4)
        + (" (the exact policy-improvement step of q_pi: the same)" if greedy == exact else "")
    )
    c.print(
        f"It is better than the random policy: v = {pl.evaluate_policy(mdp, greedy)[0]:.3f} "
        f"from cell 1 against {v_pi[0]:.3f} ({pl.compare_policies(mdp, greedy, pi)})."
    )
    try:
        from policylab.plot import save_learning_figure  # type: ignore[import-not-found,unused-ignore]
    except ImportError:
        return
    path = ctx.out_dir / "mc_prediction_slippery.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    save_learning_figure(res, path)
    ctx.figure(path)


@tour_section(61, "6. Monte Carlo control: from episodes to the optimal policy")
def mc_control_grid(ctx: TourContext) -> None:
    """MC control with exploring starts and epsilon-greedy (GLIE), against q*."""
    from policylab.tabular import mc_control

    c = ctx.console
    mdp = pl.problems.slippery_gridworld()
    episodes = 2_000 if ctx.quick else 20_000
    table = Table(title=f"MC control on the slippery gridworld, {episodes} episodes, against q*")
    for col in ("method", "max |Q - q*|", "RMS error", "greedy action optimal"):
        table.add_column(col, justify="right" if col != "method" else "left")
    for name, kw in (
        ("exploring starts", {"exploring_starts": True}),
        ("epsilon-greedy, GLIE 1/sqrt(n(s))", {}),
        ("epsilon-greedy, epsilon_k = 1/k", {"epsilon": "1/n"}),
        ("constant alpha 0.02, epsilon 0.1", {"alpha": 0.02, "epsilon": 0.1}),
    ):
        res = mc_control(mdp, episodes=episodes, seed=ctx.seed, **kw)
        err = res.error or {}
        table.add_row(
            name,
            f"{err.get('max', float('nan')):.3f}",
            f"{err.get('rms', float('nan')):.3f}",
            f"{100 * (err.get('optimal_actions') or 0):.0f}%",
        )
    c.print(table)
    c.print(
        "Epsilon-greedy control keeps exploring, so actions it rarely takes are known "
        "less well; the greedy actions, which matter, are right."
    )
