"""The tour's last section: Sutton & Barto's examples solved and drawn in the book's layouts.

The figures of the notes' own sections are drawn by those sections from what they
compute (``tour_notes``, ``tour_planning``, ``tour_mc``, ``tour_td``); this section adds
the textbook's classic pictures. matplotlib is imported only when the tour runs.
"""

from __future__ import annotations

import policylab as pl
from policylab.cli.tour import TourContext, tour_section


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
            save_solution_figure(
                mdp, res.v, res.policy, ctx.out_dir / f"14_{name}.png", q=res.q, ties=True
            )
        )
    ctx.console.print(f"Optimal values and policies drawn for {', '.join(names)}.")
