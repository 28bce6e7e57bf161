"""The tour's sections on the notes' section 5: values, Bellman equations, optimal policies."""

from __future__ import annotations

import numpy as np
from rich.table import Table

import policylab as pl
from policylab.cli.tour import TourContext, tour_section
from policylab.planning import bellman_expectation_backup, linear_programming


@tour_section(40, "5.2 Bellman equations: the robot's two policies, evaluated exactly")
def robot_policies(ctx: TourContext) -> None:
    """v_pi of the notes' deterministic and stochastic robot policies, and their comparison."""
    c = ctx.console
    mdp = pl.problems.recycling_robot()
    det = pl.problems.recycling_robot_deterministic_policy(mdp)
    sto = pl.problems.recycling_robot_stochastic_policy(mdp)
    v_det = pl.evaluate_policy(mdp, det)
    v_sto = pl.evaluate_policy(mdp, sto)
    c.print(
        "v_pi(s) = sum_a pi(a|s) sum_{s', r} p(s', r | s, a) [r + gamma v_pi(s')], gamma = 0.9,",
        markup=False,
    )
    c.print("solved as the linear system v = r_pi + gamma P_pi v:")
    table = Table(title="State values of the robot's policies")
    table.add_column("state")
    table.add_column("deterministic (low: recharge)", justify="right")
    table.add_column("stochastic (low: .5/.4/.1)", justify="right")
    for i, s in enumerate(mdp.states):
        table.add_row(str(s), f"{v_det[i]:.4f}", f"{v_sto[i]:.4f}")
    c.print(table)
    from policylab.plot import small_mdp_figure

    for name, v, pol in (("deterministic", v_det, det), ("stochastic", v_sto, sto)):
        ctx.save(
            small_mdp_figure(mdp, v, pol, title=f"Recycling robot, the {name} policy: v_pi"),
            f"04_robot_{name}_policy.png",
        )
    check = bellman_expectation_backup(mdp, v_det, det)
    c.print(
        f"Bellman check: max |T_pi v - v| = {np.abs(check - v_det).max():.1e} "
        "(v is the fixed point)"
    )
    c.print(
        "Partial order (notes 5.3): deterministic vs stochastic is "
        f"[bold]{pl.compare_policies(mdp, det, sto)}[/] (v is at least as large in every state)."
    )


@tour_section(45, "5.4-5.5 Action values and the robot's optimal policy")
def robot_optimum(ctx: TourContext) -> None:
    """q_* of the robot and the greedy policy pi_*, by three independent solvers."""
    c = ctx.console
    mdp = pl.problems.recycling_robot()
    vi = pl.value_iteration(mdp, tol=1e-10)
    pi = pl.policy_iteration(mdp)
    lp = linear_programming(mdp)
    table = Table(title="v_* by three methods")
    for col in ("method", "iterations", "v_*(high)", "v_*(low)", "error bound"):
        table.add_column(col, justify="right")
    for res in (vi, pi, lp):
        bound = "-" if res.error_bound is None else f"{res.error_bound:.1e}"
        table.add_row(res.method, str(res.iterations), f"{res.v[0]:.6f}", f"{res.v[1]:.6f}", bound)
    c.print(table)
    q = pl.action_values(mdp, pi.v)
    qt = Table(title="q_*(s, a) = r(s, a) + gamma sum p(s'|s, a) v_*(s')")
    qt.add_column("state")
    for a in mdp.actions:
        qt.add_column(str(a), justify="right")
    for i, s in enumerate(mdp.states):
        qt.add_row(str(s), *[f"{q[i, j]:.3f}" if np.isfinite(q[i, j]) else "-" for j in range(3)])
    c.print(qt)
    from policylab.plot import small_mdp_figure

    ctx.save(
        small_mdp_figure(mdp, pi.v, pi.policy, q=q, title="Recycling robot: v_*, pi_* and q_*"),
        "05_robot_optimal.png",
    )
    c.print(
        f"pi_* = greedy(q_*): {pl.greedy_policy(mdp, q).to_dict()} -- the notes' "
        "deterministic policy is optimal."
    )


@tour_section(50, "5. The mountain gridworld: the bad policy against the optimal one")
def mountain_optimum(ctx: TourContext) -> None:
    """The notes' bad policy (-6 at the start, -5 to its right) against v_* and pi_*."""
    c = ctx.console
    mdp = pl.problems.mountain_gridworld()
    assert mdp.grid is not None
    bad = pl.problems.mountain_gridworld_bad_policy(mdp)
    v_bad = pl.evaluate_policy(mdp, bad)
    res = pl.policy_iteration(mdp)
    arrows = {"up": "^", "down": "v", "left": "<", "right": ">"}
    for title, v, pol in (("bad policy", v_bad, bad), ("optimal policy", res.v, res.policy)):
        grid = mdp.grid.to_array(v)
        acts = pol.action_indices()
        table = Table(title=f"{title}: v(s) and pi(s) (row 0 at the top)")
        for col in range(grid.shape[1]):
            table.add_column(f"col {col}", justify="center")
        for r in range(grid.shape[0]):
            cells = []
            for col in range(grid.shape[1]):
                s = mdp.grid.state_at((r, col))
                kind = mdp.grid.kinds.get((r, col), "")
                if s is None or mdp.terminal[s]:
                    cells.append(f"{kind} 0")
                else:
                    cells.append(
                        f"{arrows[str(mdp.actions[acts[s]])]} {grid[r, col]:+.0f} ({kind})"
                    )
            table.add_row(*cells)
        c.print(table)
    start, right = mdp.state_index((2, 0)), mdp.state_index((2, 1))
    c.print(
        f"bad policy: v(start) = {v_bad[start]:g}, v(right of start) = {v_bad[right]:g} "
        "(the notes: -6, -5); "
        f"optimum: v_*(start) = {res.v[start]:g}, v_*(right of start) = {res.v[right]:g}."
    )
    from policylab.plot import gridworld_figure

    ctx.save(
        gridworld_figure(mdp, v_bad, bad, title="Mountain gridworld: the notes' bad policy"),
        "06_mountain_bad_policy.png",
    )
    ctx.save(
        gridworld_figure(
            mdp,
            res.v,
            pl.optimal_actions(mdp, res.q),  # every optimal action, as in Figure 3.5
            q=pl.action_values(mdp, res.v),
            title="Mountain gridworld: v_*, pi_* and q_*",
        ),
        "07_mountain_optimal.png",
    )
    q = pl.action_values(mdp, res.v)
    c.print(
        "q_*(start, .) = "
        + ", ".join(f"{a}: {q[start, j]:g}" for j, a in enumerate(mdp.actions))
        + f"; greedy: {mdp.actions[int(np.argmax(q[start]))]}."
    )
    c.print(
        f"compare_policies(optimal, bad) = [bold]{pl.compare_policies(mdp, res.policy, bad)}[/]"
    )
