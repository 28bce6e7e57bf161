"""Value and policy figures for problems that are not gridworlds.

- small problems (a handful of states, the recycling robot): values as bars beside
  the policy (and q) as a table image;
- one-dimensional problems (``mdp.meta["x"]``, the gambler, the random walk): v
  against x above the policy, as Sutton & Barto's Figure 4.3;
- two-dimensional state spaces (a :class:`~policylab.GridLayout` with ``moves=()``,
  Jack's car rental): the policy as a heat map with its action in each region and v
  beside it, as Figure 4.2;
- Blackjack (``mdp.meta["blackjack"]``, states (player sum, dealer card, usable
  ace)): v and the policy for usable ace / no usable ace, as Figure 5.2.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.colors import BoundaryNorm, ListedColormap

from policylab.exceptions import InvalidArgumentError
from policylab.plot._common import (
    BLOCKED,
    cell_text_color,
    check_q,
    check_values,
    fmt,
    is_numeric_labels,
    new_figure,
    number_format,
    policy_probs,
    title_of,
    value_norm,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = [
    "MAX_TABLE_STATES",
    "blackjack_figure",
    "draw_policy_table",
    "draw_value_bars",
    "line_figure",
    "policy_map_figure",
    "small_mdp_figure",
]

#: The most states a bar chart and table image can show legibly.
MAX_TABLE_STATES = 40
#: The most actions a table image can show legibly.
MAX_TABLE_ACTIONS = 12


def _cmap(name: str):  # type: ignore[no-untyped-def]
    import matplotlib

    return matplotlib.colormaps[name].with_extremes(bad=BLOCKED)


# ---------------------------------------------------------------------- small problems
def _require_small(mdp: FiniteMDP) -> None:
    if mdp.n_states > MAX_TABLE_STATES or mdp.n_actions > MAX_TABLE_ACTIONS:
        raise InvalidArgumentError(
            f"a bar chart and table image fit problems of at most {MAX_TABLE_STATES} states "
            f"and {MAX_TABLE_ACTIONS} actions; {mdp.name!r} has {mdp.n_states} states and "
            f"{mdp.n_actions} actions and no grid layout (mdp.grid) or abscissa "
            "(mdp.meta['x']) to draw it by"
        )


def draw_value_bars(ax: Axes, mdp: FiniteMDP, v: ArrayLike, *, label: str = "v(s)") -> None:
    """One bar per state with its value written on it (terminal states hatched)."""
    vals = check_values(mdp, v)
    names = [str(s) for s in mdp.states]
    colours = ["tab:red" if x < 0 else "tab:blue" for x in np.nan_to_num(vals)]
    bars = ax.bar(range(len(vals)), np.nan_to_num(vals), color=colours, edgecolor="black", lw=0.6)
    for s, bar in enumerate(bars):
        if mdp.terminal[s]:
            bar.set_hatch("//")
            bar.set_facecolor("0.85")
    form = number_format(vals)
    ax.bar_label(bars, labels=[fmt(form, x) for x in vals], padding=2, fontsize=8)
    ax.axhline(0, color="black", lw=0.8)
    finite = vals[np.isfinite(vals)]
    lo = min(0.0, float(finite.min())) if finite.size else 0.0
    hi = max(0.0, float(finite.max())) if finite.size else 1.0
    pad = 0.18 * ((hi - lo) or 1.0)
    ax.set_ylim(lo - (pad if lo < 0 else 0.0), hi + (pad if hi > 0 or lo == 0 else 0.0) + 1e-12)
    ax.set_xticks(range(len(vals)), names, rotation=0 if len(vals) <= 8 else 60, fontsize=8)
    ax.set_xlabel("state s" + (" (hatched: terminal)" if mdp.terminal.any() else ""))
    ax.set_ylabel(label)


def draw_policy_table(ax: Axes, mdp: FiniteMDP, table: ArrayLike, *, kind: str = "policy") -> None:
    """An (S, A) table as an image with its numbers: pi(a|s) (``kind="policy"``) or q(s, a).

    Unavailable actions and rows of terminal states are dark and show "—".
    """
    arr = np.asarray(table, dtype=np.float64).copy()
    shown = np.where(mdp.action_mask, arr, np.nan)
    if kind == "policy":
        norm_lo, norm_hi, cmap = 0.0, 1.0, "Blues"
        from matplotlib.colors import Normalize

        norm = Normalize(norm_lo, norm_hi)
        form = "{:.2f}"
        if np.allclose(np.nan_to_num(shown) % 1.0, 0.0):
            form = "{:.0f}"
    else:
        norm, cmap = value_norm(shown)
        form = number_format(shown)
    cm = _cmap(cmap)
    ax.imshow(np.ma.masked_invalid(shown), cmap=cm, norm=norm, aspect="auto")
    S, A = shown.shape
    for s in range(S):
        for a in range(A):
            x = shown[s, a]
            text = fmt(form, x) if np.isfinite(x) else "—"
            ax.text(
                a,
                s,
                text,
                ha="center",
                va="center",
                fontsize=9,
                color=cell_text_color(cm, norm, x) if np.isfinite(x) else "white",
            )
    ax.set_xticks(range(A), [str(a) for a in mdp.actions], fontsize=8)
    ax.set_yticks(range(S), [str(s) for s in mdp.states], fontsize=8)
    ax.set_xlabel("action a")
    ax.set_ylabel("state s")
    ax.tick_params(length=0)
    for x in np.arange(-0.5, A, 1.0):
        ax.axvline(x, color="white", lw=1)
    for y in np.arange(-0.5, S, 1.0):
        ax.axhline(y, color="white", lw=1)


def small_mdp_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None = None,
    policy: Policy | ArrayLike | None = None,
    *,
    q: ArrayLike | None = None,
    title: str | None = None,
    value_label: str = "v(s)",
) -> Figure:
    """A small problem's solution: values as bars, the policy and q as table images.

    Raises:
        InvalidArgumentError: If the problem has too many states or actions to show,
            or nothing is given to draw.
    """
    _require_small(mdp)
    parts = [x for x in (v, policy, q) if x is not None]
    if not parts:
        raise InvalidArgumentError("small_mdp_figure needs at least one of v, policy or q")
    S, A = mdp.n_states, mdp.n_actions
    widths = []
    if v is not None:
        widths.append(max(3.0, 0.5 * S + 1.2))
    if policy is not None:
        widths.append(max(2.8, 0.75 * A + 1.4))
    if q is not None:
        widths.append(max(2.8, 0.75 * A + 1.4))
    fig = new_figure(sum(widths) + 0.5, max(3.2, 0.3 * S + 1.8))
    axes = fig.subplots(1, len(parts), squeeze=False, width_ratios=widths)[0]
    i = 0
    if v is not None:
        draw_value_bars(axes[i], mdp, v, label=value_label)
        axes[i].set_title(f"state values {value_label}")
        i += 1
    if policy is not None:
        draw_policy_table(axes[i], mdp, policy_probs(mdp, policy), kind="policy")
        axes[i].set_title("policy π(a|s)")
        i += 1
    if q is not None:
        draw_policy_table(axes[i], mdp, check_q(mdp, q), kind="q")
        axes[i].set_title("action values q(s, a)")
    fig.suptitle(title_of(mdp, "Solution", title))
    return fig


# ---------------------------------------------------------------------- 1-D problems
def _abscissa(mdp: FiniteMDP) -> NDArray[np.float64]:
    x = mdp.meta.get("x")
    if x is None:
        raise InvalidArgumentError(
            f"a line figure needs the abscissa of each state (mdp.meta['x']); {mdp.name!r} has none"
        )
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidArgumentError(
            f"{mdp.name!r}: mdp.meta['x'] must hold one number per state; got {type(x).__name__}"
        ) from None
    if arr.shape != (mdp.n_states,):
        raise InvalidArgumentError(
            f"{mdp.name!r}: mdp.meta['x'] has shape {arr.shape}; expected ({mdp.n_states},), "
            "one number per state"
        )
    return arr


def line_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None = None,
    policy: Policy | ArrayLike | None = None,
    *,
    extra_values: dict[str, ArrayLike] | None = None,
    title: str | None = None,
    value_label: str = "v(s)",
) -> Figure:
    """A 1-D problem: v against x above the policy, as Sutton & Barto's Figure 4.3.

    Terminal states are left out of both panels (their value is 0 by definition).
    Numeric actions (the gambler's stakes) are drawn as bars of the chosen action;
    other actions as the probability of each action against x. Problems with a single
    action (the random walk) get no policy panel.

    Args:
        mdp: A problem with ``mdp.meta["x"]`` (NaN for states not drawn) and
            optionally ``meta["xlabel"]``, ``meta["xticklabels"]`` (one per drawn
            state) and ``meta["action_label"]``.
        v: Values to draw.
        policy: Policy to draw.
        extra_values: More value curves drawn on the value panel, by legend label
            (for example estimates after 10 and 100 episodes against the true values).
        title: Figure title.
        value_label: Axis label of the value panel.
    """
    x = _abscissa(mdp)
    if v is None and policy is None and not extra_values:
        raise InvalidArgumentError("line_figure needs v, policy or extra_values to draw")
    live = ~mdp.terminal & np.isfinite(x)  # states without an abscissa are not drawn
    order = np.argsort(x[live], kind="stable")
    xs = x[live][order]
    xlabel = str(mdp.meta.get("xlabel", "state"))
    show_policy = policy is not None and mdp.n_actions > 1
    has_values = v is not None or bool(extra_values)
    n = int(has_values) + int(show_policy)
    if n == 0:
        raise InvalidArgumentError(
            f"{mdp.name!r} has a single action, so its policy has nothing to show; pass v"
        )
    fig = new_figure(7.0, 3.0 * n + 0.6)
    axes = fig.subplots(n, 1, squeeze=False, sharex=True)[:, 0]
    i = 0
    if has_values:
        ax = axes[i]
        for lab, arr in (extra_values or {}).items():
            vals = check_values(mdp, arr, lab)[live][order]
            ax.plot(
                xs, vals, marker="o" if len(xs) <= 30 else None, ms=3, lw=1.2, label=lab, alpha=0.85
            )
        if v is not None:
            vals = check_values(mdp, v)[live][order]
            ax.plot(
                xs,
                vals,
                color="black",
                lw=1.8,
                marker="o" if len(xs) <= 30 else None,
                ms=4,
                label=value_label if extra_values else None,
            )
        if extra_values:
            ax.legend(fontsize=8, frameon=False)
        ax.set_ylabel(value_label)
        ax.set_title(f"state values {value_label}")
        ax.grid(alpha=0.3)
        i += 1
    if show_policy:
        ax = axes[i]
        probs = policy_probs(mdp, policy)[live][order]  # type: ignore[arg-type]
        action_label = str(mdp.meta.get("action_label", "action"))
        if is_numeric_labels(mdp.actions):
            acts = np.asarray(mdp.actions, dtype=np.float64)
            det = bool(np.all(np.isclose(probs.max(axis=1), 1.0)))
            if det:
                chosen = acts[probs.argmax(axis=1)]
                width = float(np.min(np.diff(xs))) * 0.8 if len(xs) > 1 else 0.8
                ax.bar(xs, chosen, width=width, color="tab:blue")
                ax.plot(xs, chosen, "o", color="tab:blue", ms=3)  # a chosen 0 stays visible
                ax.set_title(f"policy: {action_label} chosen in each state")
            else:
                si, ai = np.nonzero(probs > 1e-3)
                ax.scatter(xs[si], acts[ai], s=60 * probs[si, ai], color="tab:blue")
                ax.set_title(f"policy: {action_label} (dot area ∝ probability)")
            ax.set_ylabel(action_label)
        else:
            for a, act in enumerate(mdp.actions):
                ax.plot(
                    xs,
                    probs[:, a],
                    marker="o" if len(xs) <= 30 else None,
                    ms=3,
                    label=f"π({act}|s)",
                )
            ax.set_ylim(-0.05, 1.05)
            ax.set_ylabel("probability")
            ax.legend(fontsize=8, frameon=False)
            ax.set_title("policy π(a|s)")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(xlabel)
    labels = [mdp.states[s] for s in np.flatnonzero(live)[order]]
    ticklabels = mdp.meta.get("xticklabels")
    if ticklabels is not None and len(ticklabels) == len(xs):  # the problem names them
        axes[-1].set_xticks(xs, [str(t) for t in ticklabels])
    elif len(xs) <= 20:  # few states: name each one on the axis
        names = [str(lab) for lab in labels]
        same = all(_same_number(lab, x) for lab, x in zip(labels, xs, strict=True))
        axes[-1].set_xticks(xs, [fmt("{:g}", x) for x in xs] if same else names)
    fig.suptitle(title_of(mdp, "Solution", title))
    return fig


# ---------------------------------------------------------------------- 2-D state spaces
def _require_plane(mdp: FiniteMDP) -> Any:
    grid = mdp.grid
    if grid is None or grid.moves:
        raise InvalidArgumentError(
            f"a policy map needs a 2-D state space (mdp.grid with moves=()); {mdp.name!r} "
            + ("has no grid layout" if grid is None else "is a gridworld: use gridworld_figure")
        )
    return grid


def policy_map_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None = None,
    policy: Policy | ArrayLike | None = None,
    *,
    title: str | None = None,
    value_label: str = "v(s)",
) -> Figure:
    """A 2-D state space: the policy as a heat map of its action, v beside it (Figure 4.2).

    Row 0 of the layout is drawn at the bottom (the axes are counts, not a map).
    Numeric actions get a diverging scale with the action written in each region;
    other actions get one colour each and a legend. ``mdp.meta["axis_labels"]`` gives
    the (row, column) axis names.
    """
    grid = _require_plane(mdp)
    if v is None and policy is None:
        raise InvalidArgumentError("policy_map_figure needs v or policy to draw")
    rows, cols = grid.shape
    ylab, xlab = _axis_labels(mdp)
    n = int(v is not None) + int(policy is not None)
    fig = new_figure(5.0 * n + 0.6, 4.6)
    axes = fig.subplots(1, n, squeeze=False)[0]
    i = 0
    if policy is not None:
        ax = axes[i]
        probs = policy_probs(mdp, policy)
        idx = probs.argmax(axis=1)
        idx_grid = grid.to_array(np.where(mdp.terminal, np.nan, idx))
        if is_numeric_labels(mdp.actions):
            acts = np.asarray(mdp.actions, dtype=np.float64)
            val = np.where(np.isfinite(idx_grid), acts[np.nan_to_num(idx_grid).astype(int)], np.nan)
            used = np.unique(val[np.isfinite(val)])
            top = max(1.0, float(np.max(np.abs(used)))) if used.size else 1.0
            levels = np.arange(np.floor(-top) - 0.5, np.ceil(top) + 1.0, 1.0)
            cm = _cmap("RdBu")
            norm = BoundaryNorm(levels, cm.N)
            im = ax.imshow(
                np.ma.masked_invalid(val),
                cmap=cm,
                norm=norm,
                origin="lower",
                interpolation="nearest",
            )
            step = max(1, int(np.ceil(len(levels) / 12)))
            ticks = np.arange(np.floor(-top), np.ceil(top) + 1, step)
            fig.colorbar(
                im,
                ax=ax,
                shrink=0.85,
                ticks=ticks,
                label=str(mdp.meta.get("action_label", "action")),
            )
            if rows * cols <= 625:
                form = number_format(used)
                for r in range(rows):
                    for c in range(cols):
                        if np.isfinite(val[r, c]):
                            ax.text(
                                c,
                                r,
                                fmt(form, val[r, c]),
                                ha="center",
                                va="center",
                                fontsize=5 if cols > 12 else 7,
                                color=cell_text_color(cm, norm, val[r, c]),
                            )
        else:
            A = mdp.n_actions
            palette = [_cmap("tab10")(k % 10) for k in range(A)]
            cm = ListedColormap(palette).with_extremes(bad=BLOCKED)
            ax.imshow(
                np.ma.masked_invalid(idx_grid),
                cmap=cm,
                vmin=-0.5,
                vmax=A - 0.5,
                origin="lower",
                interpolation="nearest",
            )
            from matplotlib.patches import Patch

            ax.legend(
                handles=[Patch(color=palette[k], label=str(a)) for k, a in enumerate(mdp.actions)],
                loc="upper left",
                bbox_to_anchor=(1.01, 1.0),
                fontsize=8,
                title="action",
            )
        ax.set_title("policy π(s)")
        ax.set_xlabel(xlab)
        ax.set_ylabel(ylab)
        i += 1
    if v is not None:
        ax = axes[i]
        vals = check_values(mdp, v)
        norm_v, cmap_v = value_norm(vals[~mdp.terminal])
        im = ax.imshow(
            np.ma.masked_invalid(grid.to_array(vals)),
            cmap=_cmap(cmap_v),
            norm=norm_v,
            origin="lower",
            interpolation="nearest",
        )
        fig.colorbar(im, ax=ax, shrink=0.85, label=value_label)
        ax.set_title(f"state values {value_label}")
        ax.set_xlabel(xlab)
        ax.set_ylabel(ylab)
    from matplotlib.ticker import MaxNLocator

    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(title_of(mdp, "Solution", title))
    return fig


def _axis_labels(mdp: FiniteMDP) -> tuple[str, str]:
    """(row axis, column axis) names from ``mdp.meta["axis_labels"]``."""
    labs = mdp.meta.get("axis_labels")
    if labs is None:
        return "row", "column"
    if isinstance(labs, str) or len(labs) != 2:
        raise InvalidArgumentError(
            f"{mdp.name!r}: mdp.meta['axis_labels'] must be (row axis, column axis); got {labs!r}"
        )
    return str(labs[0]), str(labs[1])


# ---------------------------------------------------------------------- Blackjack
def _blackjack_states(mdp: FiniteMDP) -> list[tuple[int, int, int, bool]]:
    """(state index, player sum, dealer card, usable ace) of every non-terminal state."""
    if not mdp.meta.get("blackjack"):
        raise InvalidArgumentError(
            f"a Blackjack figure needs the Blackjack problem (mdp.meta['blackjack']); "
            f"{mdp.name!r} is another problem"
        )
    out = []
    for s, lab in enumerate(mdp.states):
        if mdp.terminal[s]:
            continue
        if not (isinstance(lab, tuple) and len(lab) == 3):
            raise InvalidArgumentError(
                f"{mdp.name!r}: Blackjack states must be labelled (player_sum, dealer_card, "
                f"usable_ace); got {lab!r}"
            )
        ace = lab[2]
        if not isinstance(ace, (bool, int, np.bool_)) or isinstance(ace, str):
            continue  # a state of its own kind, e.g. (21, d, "natural"): not on the chart
        out.append((s, int(lab[0]), _dealer_value(lab[1]), bool(ace)))
    if not out:
        raise InvalidArgumentError(f"{mdp.name!r} has no non-terminal Blackjack state to draw")
    return out


def _dealer_value(card: Hashable) -> int:
    if isinstance(card, str) and card.strip().upper() in ("A", "ACE"):
        return 1
    return int(card)  # type: ignore[call-overload, no-any-return]


def blackjack_figure(
    mdp: FiniteMDP,
    v: ArrayLike | None = None,
    policy: Policy | ArrayLike | None = None,
    *,
    title: str | None = None,
    value_label: str = "v(s)",
    player_sums: tuple[int, int] | None = (12, 21),
) -> Figure:
    """Blackjack in the layout of Sutton & Barto's Figure 5.2.

    Rows: usable ace, no usable ace. Columns: v as a heat map and the policy (the
    action with the highest probability in each state). The dealer's showing card
    (A, 2, ..., 10) runs along x, the player's sum up the y axis. States whose third
    label is not a usable-ace flag (a natural, ``(21, d, "natural")``) are not charted.

    Args:
        mdp: The Blackjack problem (``meta["blackjack"]``, states labelled
            (player_sum, dealer_card, usable_ace)).
        v: Values to draw.
        policy: Policy to draw.
        title: Figure title.
        value_label: Colour-bar label.
        player_sums: Range of player sums charted (the book's 12..21, below which
            hitting is always right); None charts every sum.
    """
    info = _blackjack_states(mdp)
    if player_sums is not None:
        lo, hi = player_sums
        info = [x for x in info if lo <= x[1] <= hi]
        if not info:
            raise InvalidArgumentError(
                f"{mdp.name!r} has no Blackjack state with a player sum in {lo}..{hi}"
            )
    if v is None and policy is None:
        raise InvalidArgumentError("blackjack_figure needs v or policy to draw")
    sums = sorted({p for _, p, _, _ in info})
    dealers = sorted({d for _, _, d, _ in info})
    p_index = {p: i for i, p in enumerate(sums)}
    d_index = {d: i for i, d in enumerate(dealers)}
    cols = [x for x in ((v, "value"), (policy, "policy")) if x[0] is not None]
    fig = new_figure(4.4 * len(cols) + 0.8, 7.6)
    axes = fig.subplots(2, len(cols), squeeze=False)
    vals = check_values(mdp, v) if v is not None else None
    probs = policy_probs(mdp, policy) if policy is not None else None
    norm_v, cmap_v = value_norm(vals[[s for s, *_ in info]]) if vals is not None else (None, "")
    A = mdp.n_actions
    short = [str(a)[:1].upper() for a in mdp.actions]
    if len(set(short)) < A:
        short = [str(a) for a in mdp.actions]
    palette = ["#f4a582", "#92c5de", "#b2df8a", "#cab2d6", "#fdbf6f"]
    for row, ace in enumerate((True, False)):
        for col, (_, what) in enumerate(cols):
            ax = axes[row, col]
            img = np.full((len(sums), len(dealers)), np.nan)
            for s, p, d, u in info:
                if u != ace:
                    continue
                if what == "value":
                    img[p_index[p], d_index[d]] = vals[s]  # type: ignore[index]
                else:
                    img[p_index[p], d_index[d]] = float(np.argmax(probs[s]))  # type: ignore[index]
            if what == "value":
                cm = _cmap(cmap_v)
                ax.imshow(
                    np.ma.masked_invalid(img),
                    cmap=cm,
                    norm=norm_v,
                    origin="lower",
                    aspect="auto",
                    interpolation="nearest",
                )
                for i in range(len(sums)):
                    for j in range(len(dealers)):
                        if np.isfinite(img[i, j]):
                            ax.text(
                                j,
                                i,
                                _short_number(float(img[i, j])),
                                ha="center",
                                va="center",
                                fontsize=5.5,
                                color=cell_text_color(cm, norm_v, img[i, j]),  # type: ignore[arg-type]
                            )
                ax.set_title(f"{value_label}, {'usable ace' if ace else 'no usable ace'}")
            else:
                cm = ListedColormap([palette[k % len(palette)] for k in range(A)]).with_extremes(
                    bad="white"
                )
                ax.imshow(
                    np.ma.masked_invalid(img),
                    cmap=cm,
                    vmin=-0.5,
                    vmax=A - 0.5,
                    origin="lower",
                    aspect="auto",
                    interpolation="nearest",
                )
                for i in range(len(sums)):
                    for j in range(len(dealers)):
                        if np.isfinite(img[i, j]):
                            ax.text(
                                j, i, short[int(img[i, j])], ha="center", va="center", fontsize=7
                            )
                ax.set_title(f"policy π(s), {'usable ace' if ace else 'no usable ace'}")
                if row == 0:
                    from matplotlib.patches import Patch

                    ax.legend(
                        handles=[
                            Patch(color=palette[k % len(palette)], label=str(a))
                            for k, a in enumerate(mdp.actions)
                        ],
                        loc="upper left",
                        bbox_to_anchor=(1.01, 1.0),
                        fontsize=8,
                        title="action",
                    )
            ax.set_xticks(range(len(dealers)), [_dealer_name(d) for d in dealers], fontsize=8)
            ax.set_yticks(range(len(sums)), [str(p) for p in sums], fontsize=7)
            ax.set_xlabel("dealer showing")
            ax.set_ylabel("player sum")
    if vals is not None:
        from matplotlib.cm import ScalarMappable

        fig.colorbar(
            ScalarMappable(norm=norm_v, cmap=_cmap(cmap_v)),
            ax=list(axes[:, 0]),
            shrink=0.6,
            label=value_label,
        )
    fig.suptitle(title_of(mdp, "Blackjack (layout of S&B Figure 5.2)", title))
    return fig


def _short_number(x: float) -> str:
    """Two decimals without the leading zero (".43", "-.12"), as the book's tables."""
    text = f"{x:.2f}"
    if text.startswith("0."):
        return text[1:]
    if text.startswith("-0."):
        return "-" + text[2:]
    return text


def _same_number(label: Hashable, x: float) -> bool:
    try:
        return float(label) == float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False


def _dealer_name(d: int) -> str:
    return "A" if d == 1 else str(d)
