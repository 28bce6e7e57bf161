"""Gridworld figures: values in each cell, policies as arrows, Q-tables as triangles.

Everything here reads the MDP's :class:`~policylab.GridLayout` (``mdp.grid``): which
cell each state occupies, the kind of every cell (mountain, wall, cliff, goal, ...),
thin walls, and the move of each action. Nothing is guessed from labels. Row 0 is
drawn at the top, as in the map the problem was built from.
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.patches import Circle, Rectangle

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.returns import discounted_return
from policylab.plot._common import (
    BLOCKED,
    cell_text_color,
    check_q,
    check_values,
    fmt,
    new_figure,
    number_format,
    policy_probs,
    title_of,
    value_norm,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from numpy.typing import ArrayLike

    from policylab.envs.rollout import Episode
    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.grid import Cell, GridLayout
    from policylab.mdp.policy import Policy

__all__ = [
    "draw_grid_policy",
    "draw_grid_values",
    "draw_q_table",
    "episode_figure",
    "gridworld_figure",
    "q_table_figure",
]

#: Kinds drawn with a hatch: places a walker would rather avoid.
HAZARD_KINDS = frozenset({"mountain", "cliff", "hole", "lava", "trap", "water"})

_COMPASS = {(-1, 0): "up", (1, 0): "down", (0, -1): "left", (0, 1): "right"}


def require_grid(mdp: FiniteMDP, figure: str) -> GridLayout:
    """The MDP's grid layout with its cells and moves, or a clear refusal.

    Raises:
        InvalidArgumentError: If the MDP has no grid layout or its layout has no moves.
    """
    grid = mdp.grid
    if grid is None:
        raise InvalidArgumentError(
            f"{figure} needs a grid-shaped problem (mdp.grid, a GridLayout saying which cell "
            f"each state occupies); {mdp.name!r} has none"
        )
    if not grid.moves:
        raise InvalidArgumentError(
            f"{figure} needs the move of each action (grid.moves); {mdp.name!r} lays its "
            "states on a grid without moves (a 2-D state space: use policy_map_figure)"
        )
    if len(grid.moves) != mdp.n_actions:
        raise InvalidArgumentError(
            f"{mdp.name!r}: grid.moves has {len(grid.moves)} moves for {mdp.n_actions} actions"
        )
    return grid


def _plain_kind(grid: GridLayout) -> str | None:
    """The most common kind among state cells: it goes unlabelled."""
    counts = Counter(grid.kinds.get(c, "") for c in grid.cells)
    return counts.most_common(1)[0][0] if counts else None


def _base_grid(ax: Axes, mdp: FiniteMDP, grid: GridLayout, *, label_states: bool = True) -> None:
    """Axes limits, cell borders, walls, thin walls, kind labels, terminal frames."""
    rows, cols = grid.shape
    ax.set_xlim(-0.5, cols - 0.5)
    ax.set_ylim(rows - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks(range(cols))
    ax.set_yticks(range(rows))
    ax.tick_params(length=0, labelsize=8)
    ax.set_xlabel("column")
    if grid.wind is not None:  # the windy gridworld: each column's upward push under it
        ax.set_xticks(
            range(cols), [f"{c}\n↑{w}" if w else f"{c}\n·" for c, w in enumerate(grid.wind)]
        )
        ax.set_xlabel("column (↑ wind strength)")
    ax.set_ylabel("row")
    for r in range(rows + 1):
        ax.axhline(r - 0.5, color="white", lw=1.0, zorder=2)
    for c in range(cols + 1):
        ax.axvline(c - 0.5, color="white", lw=1.0, zorder=2)
    for spine in ax.spines.values():
        spine.set_visible(False)
    occupied = set(grid.cells)
    for r in range(rows):
        for c in range(cols):
            if (r, c) not in occupied:
                ax.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, color=BLOCKED, zorder=1.5))
                kind = grid.kinds.get((r, c), "")
                if kind and cols <= 16:
                    ax.text(
                        c, r, kind, ha="center", va="center", color="white", fontsize=7, zorder=5
                    )
    plain = _plain_kind(grid)
    small = 6 if cols > 8 else 7
    label_states = label_states and rows * cols <= 30
    for s, (r, c) in enumerate(grid.cells):
        kind = grid.kinds.get((r, c), "")
        if kind in HAZARD_KINDS:
            ax.add_patch(
                Rectangle(
                    (c - 0.5, r - 0.5),
                    1,
                    1,
                    fill=False,
                    hatch="///",
                    edgecolor="0.35",
                    lw=0,
                    zorder=1.6,
                )
            )
        if kind and kind != plain:
            ax.text(
                c - 0.45,
                r - 0.45,
                kind,
                ha="left",
                va="top",
                fontsize=small,
                zorder=6,
                bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.75},
            )
        if mdp.terminal[s]:
            ax.add_patch(
                Rectangle(
                    (c - 0.46, r - 0.46), 0.92, 0.92, fill=False, ec="black", lw=2.0, zorder=4
                )
            )
        lab = mdp.states[s]
        if label_states and lab != (r, c):
            ax.text(
                c + 0.45,
                r + 0.45,
                f"s={lab}",
                ha="right",
                va="bottom",
                fontsize=small,
                color="0.2",
                zorder=6,
                bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.75},
            )
    for wall in grid.thin_walls:
        a, b = sorted(wall)
        if a[0] == b[0]:  # side by side: a vertical wall
            x = max(a[1], b[1]) - 0.5
            ax.plot(
                [x, x],
                [a[0] - 0.5, a[0] + 0.5],
                color="black",
                lw=5,
                zorder=7,
                solid_capstyle="butt",
            )
        else:  # one above the other: a horizontal wall
            y = max(a[0], b[0]) - 0.5
            ax.plot(
                [a[1] - 0.5, a[1] + 0.5],
                [y, y],
                color="black",
                lw=5,
                zorder=7,
                solid_capstyle="butt",
            )


def draw_grid_values(
    ax: Axes,
    mdp: FiniteMDP,
    v: ArrayLike,
    *,
    norm: Normalize | None = None,
    cmap: str | None = None,
) -> None:
    """Draw per-state values as a heatmap on the grid, with the number in each cell.

    Terminal cells are framed, cells of special kinds (mountain, goal, start, cliff,
    ...) are labelled in their corner, hazards hatched, walls filled dark, thin walls
    drawn as thick lines.

    Args:
        ax: The axes to draw on.
        mdp: A grid-shaped MDP (``mdp.grid`` set).
        v: One value per state, in the order of ``mdp.states``.
        norm: Colour scale (default: diverging around 0 if values change sign).
        cmap: Colour map name (default chosen with the scale).
    """
    grid = _grid_cells_only(mdp, "a gridworld value figure")
    vals = check_values(mdp, v)
    default_norm, default_cmap = value_norm(vals)
    norm = norm or default_norm
    cm = _cmap(cmap or default_cmap)
    arr = grid.to_array(vals)
    ax.imshow(np.ma.masked_invalid(arr), cmap=cm, norm=norm, zorder=1, interpolation="nearest")
    _base_grid(ax, mdp, grid)
    form = number_format(vals)
    cols = grid.shape[1]
    size = 11 if cols <= 6 else (9 if cols <= 10 else 7)
    for s, (r, c) in enumerate(grid.cells):
        x = vals[s]
        ax.text(
            c,
            r,
            fmt(form, x),
            ha="center",
            va="center",
            fontsize=size,
            zorder=5,
            color=cell_text_color(cm, norm, x),
            fontweight="bold",
        )


def draw_grid_policy(ax: Axes, mdp: FiniteMDP, policy: Policy | ArrayLike) -> None:
    """Draw a policy as arrows from each cell's centre, one per action it may take.

    Arrow length is proportional to pi(a | s) (a deterministic policy has one long
    arrow per cell); directions come from ``mdp.grid.moves``. An action that does not
    move (a "stay" move) is a dot whose size grows with its probability. A boolean
    (S, A) array (a set of actions per state, such as all optimal actions) draws an
    arrow of the same length for each action in the set, as Sutton & Barto's Figure 3.5
    shows tied optimal actions.
    """
    grid = require_grid(mdp, "a policy arrow figure")
    as_set = _is_action_set(mdp, policy)
    probs = policy_probs(mdp, policy)
    if as_set:
        probs = (probs > 0).astype(np.float64)  # one (full) arrow length for every action
    ax.imshow(np.full(grid.shape, 0.08), cmap=_cmap("Greys"), vmin=0, vmax=1, zorder=0)
    _base_grid(ax, mdp, grid)
    live = ~mdp.terminal
    # one action per state (probability 1, and no second action in a set of ties)
    deterministic = bool(np.all((probs[live] > 0).sum(axis=1) == 1)) if live.any() else True
    write_p = not deterministic and not as_set and grid.shape[1] <= 8
    for s, (r, c) in enumerate(grid.cells):
        if mdp.terminal[s]:
            continue
        for a, (dr, dc) in enumerate(grid.moves):
            p = float(probs[s, a])
            if p < 1e-3:
                continue
            if dr == 0 and dc == 0:
                ax.add_patch(Circle((c, r), 0.05 + 0.1 * p, color="tab:blue", zorder=8))
                continue
            norm_len = float(np.hypot(dr, dc))
            ux, uy = dc / norm_len, dr / norm_len
            if deterministic:  # one arrow through the centre of the cell
                length, x0, y0 = 0.6, c - 0.3 * ux, r - 0.3 * uy
            else:  # one arrow per action, out of the centre, as long as it is likely
                length, x0, y0 = 0.1 + 0.32 * p, c + 0.04 * ux, r + 0.04 * uy
            head = min(0.13, 0.45 * length)
            ax.arrow(
                x0,
                y0,
                ux * length,
                uy * length,
                width=0.02 + 0.02 * p,
                head_width=2.4 * head,
                head_length=head,
                length_includes_head=True,
                color="tab:blue",
                zorder=8,
            )
            if write_p:
                ax.text(
                    x0 + ux * (length + 0.05),
                    y0 + uy * (length + 0.05),
                    f"{p:.2g}",
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="0.15",
                    zorder=9,
                )


def _is_action_set(mdp: FiniteMDP, policy: Policy | ArrayLike) -> bool:
    """True when ``policy`` is a boolean (S, A) set of actions rather than pi(a | s)."""
    from policylab.mdp.policy import Policy

    if isinstance(policy, Policy):
        return False
    arr = np.asarray(policy)
    return arr.dtype == np.bool_ and arr.shape == (mdp.n_states, mdp.n_actions)


def _grid_cells_only(mdp: FiniteMDP, figure: str) -> GridLayout:
    grid = mdp.grid
    if grid is None:
        raise InvalidArgumentError(
            f"{figure} needs a grid-shaped problem (mdp.grid, a GridLayout saying which cell "
            f"each state occupies); {mdp.name!r} has none"
        )
    return grid


def q_triangles(grid: GridLayout, mdp: FiniteMDP) -> list[str]:
    """The compass direction of each action, for the Q-table view.

    Raises:
        InvalidArgumentError: If the actions are not the four compass moves, one each.
    """
    dirs = [_COMPASS.get((int(m[0]), int(m[1]))) for m in grid.moves]
    if None in dirs or len(set(dirs)) != len(dirs):
        raise InvalidArgumentError(
            f"the Q-table view draws one triangle per compass move (up, down, left, right); "
            f"{mdp.name!r} has moves {list(grid.moves)} for actions {list(mdp.actions)}"
        )
    return [d for d in dirs if d is not None]


def _triangle(
    direction: str, c: float, r: float
) -> tuple[list[tuple[float, float]], tuple[float, float]]:
    """Vertices of the triangle of one direction in cell (r, c), and where its text goes."""
    tl, tr, bl, br = (c - 0.5, r - 0.5), (c + 0.5, r - 0.5), (c - 0.5, r + 0.5), (c + 0.5, r + 0.5)
    centre = (c, r)
    if direction == "up":
        return [tl, tr, centre], (c, r - 0.3)
    if direction == "down":
        return [bl, br, centre], (c, r + 0.3)
    if direction == "left":
        return [tl, bl, centre], (c - 0.3, r)
    return [tr, br, centre], (c + 0.3, r)


def draw_q_table(
    ax: Axes,
    mdp: FiniteMDP,
    q: ArrayLike,
    *,
    norm: Normalize | None = None,
    cmap: str | None = None,
) -> None:
    """Draw action values q(s, a) as four triangles per cell (the notes' figure 9).

    Each cell is split into the triangles pointing up, down, left and right; each is
    coloured by and labelled with the value of that move. The greedy action of each
    state is written in bold and underlined by a black edge. Unavailable actions are
    dark; terminal cells are framed and left blank.

    Raises:
        InvalidArgumentError: If the problem is not a gridworld of the four compass moves.
    """
    grid = require_grid(mdp, "the Q-table view")
    dirs = q_triangles(grid, mdp)
    qa = check_q(mdp, q)
    live = mdp.action_mask
    shown = np.where(live, qa, np.nan)
    default_norm, default_cmap = value_norm(shown)
    norm = norm or default_norm
    cm = _cmap(cmap or default_cmap)
    ax.imshow(np.zeros(grid.shape), cmap=_cmap("Greys"), vmin=0, vmax=1, zorder=0)
    polys, colours, edges = [], [], []
    texts: list[tuple[float, float, str, str, bool]] = []
    form = number_format(shown)
    for s, (r, c) in enumerate(grid.cells):
        if mdp.terminal[s]:
            continue
        row = shown[s]
        best = np.nanmax(row) if np.any(np.isfinite(row)) else np.nan
        for a, d in enumerate(dirs):
            verts, (tx, ty) = _triangle(d, c, r)
            polys.append(verts)
            x = row[a]
            greedy = bool(np.isfinite(x) and np.isfinite(best) and np.isclose(x, best))
            colours.append(cm(norm(x)) if np.isfinite(x) else BLOCKED)
            edges.append("black" if greedy else "white")
            if np.isfinite(x):
                texts.append((tx, ty, fmt(form, x), cell_text_color(cm, norm, x), greedy))
    coll = PolyCollection(polys, facecolors=colours, edgecolors=edges, linewidths=0.8, zorder=1)
    ax.add_collection(coll)
    _base_grid(ax, mdp, grid)
    cols = grid.shape[1]
    size = 8 if cols <= 5 else 6
    for tx, ty, text, colour, greedy in texts:
        ax.text(
            tx,
            ty,
            text,
            ha="center",
            va="center",
            fontsize=size,
            color=colour,
            zorder=5,
            fontweight="bold" if greedy else "normal",
        )


def _cmap(name: str):  # type: ignore[no-untyped-def]
    import matplotlib

    return matplotlib.colormaps[name].with_extremes(bad="white")


def _colorbar(fig: Figure, ax: Axes | list[Axes], norm: Normalize, cmap: str, label: str) -> None:
    from matplotlib.cm import ScalarMappable

    sm = ScalarMappable(norm=norm, cmap=_cmap(cmap))
    fig.colorbar(sm, ax=ax, shrink=0.8, label=label)


def _wide(grid: GridLayout) -> bool:
    """Whether a grid is so wide that its panels go one above the other."""
    rows, cols = grid.shape
    return cols >= 2 * rows and cols > 6


def _panel_size(grid: GridLayout) -> tuple[float, float]:
    rows, cols = grid.shape
    unit = 1.2 if cols <= 6 else (0.8 if cols <= 12 else 0.5)
    return max(3.6, unit * cols), max(2.6, unit * rows)


def gridworld_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None = None,
    policy: Policy | ArrayLike | None = None,
    *,
    q: ArrayLike | None = None,
    title: str | None = None,
    value_label: str = "v(s)",
) -> Figure:
    """A gridworld solution: values, the policy as arrows and the Q-table, side by side.

    Each of ``v``, ``policy`` and ``q`` that is given gets its own panel, in that order.

    Raises:
        InvalidArgumentError: If nothing is given to draw or the MDP has no grid.
    """
    grid = _grid_cells_only(mdp, "a gridworld figure")
    panels = [x for x in (v, policy, q) if x is not None]
    if not panels:
        raise InvalidArgumentError("gridworld_figure needs at least one of v, policy or q to draw")
    w, h = _panel_size(grid)
    if _wide(grid):  # panels one above the other
        fig = new_figure(w + 1.4, (h + 0.6) * len(panels) + 0.4)
        axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    else:
        fig = new_figure(w * len(panels) + 1.2 * (v is not None) + 1.2 * (q is not None), h + 0.9)
        axes = fig.subplots(1, len(panels), squeeze=False)[0]
    i = 0
    if v is not None:
        vals = check_values(mdp, v)
        norm, cmap = value_norm(vals)
        draw_grid_values(axes[i], mdp, vals, norm=norm, cmap=cmap)
        axes[i].set_title(f"state values {value_label}")
        _colorbar(fig, axes[i], norm, cmap, value_label)
        i += 1
    if policy is not None:
        draw_grid_policy(axes[i], mdp, policy)
        probs = policy_probs(mdp, policy)
        live = ~mdp.terminal
        det = bool(np.all(np.isclose(probs[live].max(axis=1), 1.0)))
        if _is_action_set(mdp, policy):
            ties = bool((np.asarray(policy).sum(axis=1) > 1).any())
            axes[i].set_title(
                "greedy actions\n(every tied action drawn)" if ties else "policy π(s)"
            )
        else:
            axes[i].set_title(
                "policy π(s)" if det else "policy π(a|s)\n(arrow length ∝ probability)"
            )
        i += 1
    if q is not None:
        qa = check_q(mdp, q)
        norm, cmap = value_norm(np.where(mdp.action_mask, qa, np.nan))
        draw_q_table(axes[i], mdp, qa, norm=norm, cmap=cmap)
        axes[i].set_title("action values q(s, a)\n(bold: greedy action)")
        _colorbar(fig, axes[i], norm, cmap, "q(s, a)")
    fig.suptitle(title_of(mdp, "Solution", title))
    return fig


def q_table_figure(
    mdp: FiniteMDP,
    q: ArrayLike,
    *,
    reference: ArrayLike | None = None,
    labels: tuple[str, str] = ("estimate", "exact"),
    title: str | None = None,
) -> Figure:
    """The Q-table view (notes' figure 9), alone or beside a reference on one colour scale.

    Args:
        mdp: A gridworld of the four compass moves.
        q: The (S, A) action values to draw (for example a Monte Carlo estimate).
        reference: Optional (S, A) values to compare with (for example the exact q*).
        labels: Panel titles of ``q`` and ``reference``.
        title: Figure title.
    """
    grid = require_grid(mdp, "the Q-table view")
    qa = check_q(mdp, q)
    arrays = [qa]
    if reference is not None:
        arrays.append(check_q(mdp, reference, "reference"))
    shown = np.concatenate([np.where(mdp.action_mask, x, np.nan) for x in arrays])
    norm, cmap = value_norm(shown)
    w, h = _panel_size(grid)
    if _wide(grid):
        fig = new_figure(w + 1.4, (h + 0.6) * len(arrays) + 0.6)
        axes = list(fig.subplots(len(arrays), 1, squeeze=False)[:, 0])
    else:
        fig = new_figure(w * len(arrays) + 1.2, h + 0.9)
        axes = list(fig.subplots(1, len(arrays), squeeze=False)[0])
    for ax, arr, lab in zip(axes, arrays, labels, strict=False):
        draw_q_table(ax, mdp, arr, norm=norm, cmap=cmap)
        ax.set_title(f"q(s, a): {lab}")
    _colorbar(fig, axes, norm, cmap, "q(s, a)")
    if reference is not None:
        live = mdp.action_mask
        err = np.abs(arrays[0] - arrays[1])[live]
        err = err[np.isfinite(err)]
        if err.size:
            fig.supxlabel(
                f"max |{labels[0]} − {labels[1]}| = {err.max():.3g}, "
                f"mean = {err.mean():.3g} over {err.size} (state, action) pairs",
                fontsize=9,
            )
    fig.suptitle(title_of(mdp, "Q-table (bold: greedy action)", title))
    return fig


def episode_figure(
    mdp: FiniteMDP,
    episode: Episode,
    *,
    gamma: float | None = None,
    title: str | None = None,
    max_rows: int = 24,
) -> Figure:
    """One episode drawn on the grid, as the notes' figures 7 and 8 do.

    Each step t is an arrow from the cell of S_t to the cell of S_{t+1}, numbered
    t + 1; a step that stays put (a bump, or a slip into a wall) is a numbered ring.
    Beside the grid, the table of S_t, A_t, R_{t+1} and the return G_0.

    Args:
        mdp: A grid-shaped MDP.
        episode: An episode of that MDP (see :func:`policylab.rollout`).
        gamma: Discount rate of the return shown (default: the MDP's).
        title: Figure title.
        max_rows: The most steps listed in the table (the path shows them all).

    Raises:
        InvalidArgumentError: If the MDP has no grid or the episode visits states it
            does not have.
    """
    from matplotlib.patches import FancyArrowPatch

    grid = _grid_cells_only(mdp, "an episode figure")
    states = np.asarray(episode.states, dtype=np.int64)
    if states.size == 0 or states.min() < 0 or states.max() >= mdp.n_states:
        raise InvalidArgumentError(
            f"the episode visits state indices outside 0..{mdp.n_states - 1} of {mdp.name!r}"
        )
    g = mdp.gamma if gamma is None else float(gamma)
    w, h = _panel_size(grid)
    n_steps = len(episode.actions)
    n_lines = min(n_steps, max_rows) + 5 + (n_steps > max_rows)
    fig = new_figure(w + 3.4, max(h + 0.9, 0.15 * n_lines + 0.8))
    ax, ax_t = fig.subplots(1, 2, width_ratios=[w, 3.0])
    ax.imshow(np.full(grid.shape, 0.08), cmap=_cmap("Greys"), vmin=0, vmax=1, zorder=0)
    _base_grid(ax, mdp, grid)
    cm = _cmap("viridis")
    # Steps grouped by (from cell, to cell): one arrow (or ring) per move made, labelled
    # with its step numbers, or with how often it was made when there are many.
    moves: dict[tuple[Cell, Cell], list[int]] = {}
    for t in range(n_steps):
        moves.setdefault((grid.cells[states[t]], grid.cells[states[t + 1]]), []).append(t + 1)
    for ((r0, c0), (r1, c1)), steps in moves.items():
        colour = cm((steps[0] - 1) / max(n_steps - 1, 1))
        text = ",".join(map(str, steps)) if len(steps) <= 3 else f"{len(steps)}×"
        lw = 1.5 + min(len(steps), 8) * 0.4
        if (r0, c0) == (r1, c1):
            ax.add_patch(Circle((c0, r0 + 0.25), 0.1, fill=False, ec=colour, lw=lw, zorder=9))
            ax.text(
                c0,
                r0 + 0.25,
                text,
                ha="center",
                va="center",
                fontsize=6,
                zorder=10,
                bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8},
            )
            continue
        start, end = (c0, r0), (c1, r1)
        ax.add_patch(
            FancyArrowPatch(
                start,
                end,
                arrowstyle="-|>",
                mutation_scale=12,
                color=colour,
                lw=lw,
                connectionstyle="arc3,rad=0.2",
                zorder=9,
                shrinkA=8,
                shrinkB=8,
            )
        )
        # The label sits on the arc's bulge, to the right of the direction of travel.
        mx, my = (c0 + c1) / 2, (r0 + r1) / 2
        nx, ny = -(r1 - r0), (c1 - c0)
        ax.text(
            mx - 0.1 * nx,
            my - 0.1 * ny,
            text,
            fontsize=7,
            ha="center",
            va="center",
            zorder=10,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": colour},
        )
    r0, c0 = grid.cells[states[0]]
    ax.plot([c0], [r0], marker="o", ms=10, mfc="none", mec="black", mew=2, zorder=9)
    ax.set_title("path: step numbers (n×: n times), ring: stayed", fontsize=9)
    ax_t.axis("off")
    labels_s = [str(mdp.states[s]) for s in states]
    labels_a = [str(mdp.actions[a]) for a in episode.actions]
    rows_txt = ["t   S_t       A_t      R_t+1", ""]
    for t in range(min(n_steps, max_rows)):
        rows_txt.append(f"{t:<3} {labels_s[t]:<9} {labels_a[t]:<8} {episode.rewards[t]:+g}")
    if n_steps > max_rows:
        rows_txt.append(f"... ({n_steps - max_rows} more steps)")
    ending = "terminated" if episode.terminated else "truncated" if episode.truncated else "stopped"
    rows_txt.append(f"{n_steps:<3} {labels_s[n_steps]:<9} ({ending})")
    rows_txt.append("")
    rows_txt.append(f"G_0 = {discounted_return(episode.rewards, g):g}  (γ = {g:g})")
    table = ax_t.text(
        0.0,
        1.0,
        "\n".join(rows_txt),
        family="monospace",
        fontsize=8,
        va="top",
        ha="left",
        transform=ax_t.transAxes,
    )
    table.set_in_layout(False)
    fig.suptitle(title if title is not None else f"One episode — {mdp.name}")
    return fig
