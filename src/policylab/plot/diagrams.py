"""The notes' figure 1: the agent-environment interaction loop, drawn."""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

from policylab.plot._common import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["interaction_loop_figure"]


def interaction_loop_figure(*, title: str | None = None) -> Figure:
    """The agent-environment loop (notes' figure 1, Sutton & Barto's Figure 3.1).

    The agent sees S_t and R_t, picks A_t; the environment answers with R_{t+1} and
    S_{t+1}, which the agent sees at the next step.
    """
    fig = new_figure(6.4, 3.6)
    ax = fig.add_subplot()
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 6)
    ax.axis("off")
    for x, y, w, h, text, colour in (
        (3.5, 4.2, 3.0, 1.2, "Agent\npolicy π(a | s)", "#cfe2f3"),
        (3.5, 0.6, 3.0, 1.2, "Environment\ndynamics p(s', r | s, a)", "#d9ead3"),
    ):
        ax.add_patch(
            FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.1", fc=colour, ec="black", lw=1.2)
        )
        ax.text(x + w / 2, y + h / 2, text, ha="center", va="center", fontsize=10)

    def arrow(points: list[tuple[float, float]], label: str, at: tuple[float, float]) -> None:
        for a, b in itertools.pairwise(points):
            last = b == points[-1]
            ax.add_patch(
                FancyArrowPatch(
                    a,
                    b,
                    arrowstyle="-|>" if last else "-",
                    mutation_scale=14,
                    lw=1.6,
                    color="black",
                )
            )
        ax.text(
            *at,
            label,
            ha="center",
            va="center",
            fontsize=10,
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none"},
        )

    arrow([(6.6, 4.8), (8.6, 4.8), (8.6, 1.2), (6.6, 1.2)], "action\n$A_t$", (8.6, 3.0))
    arrow([(3.4, 1.0), (1.0, 1.0), (1.0, 4.6), (3.4, 4.6)], "state\n$S_{t+1}$", (1.0, 2.4))
    arrow([(3.4, 1.4), (1.9, 1.4), (1.9, 5.0), (3.4, 5.0)], "reward\n$R_{t+1}$", (1.9, 3.6))
    ax.text(
        5.0,
        3.0,
        "$S_0, A_0, R_1, S_1, A_1, R_2, S_2, \\ldots$",
        ha="center",
        va="center",
        fontsize=9,
        style="italic",
        color="0.3",
    )
    fig.suptitle(title if title is not None else "The agent-environment interaction loop")
    return fig
