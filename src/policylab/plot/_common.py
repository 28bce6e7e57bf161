"""What every figure shares: input checks, number formats, colours, saving.

Figures are built on :class:`matplotlib.figure.Figure` objects directly (never
``pyplot``), so drawing is headless (Agg), leaves no global state behind and works in
threads and on servers without a display.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.colors import Colormap, Normalize, TwoSlopeNorm
from matplotlib.figure import Figure

from policylab.exceptions import InvalidArgumentError, InvalidPolicyError, ShapeError
from policylab.mdp.policy import Policy
from policylab.validation import FIGURE_FORMATS, check_figure_path, check_float_array

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = [
    "FORMATS",
    "cell_text_color",
    "check_q",
    "check_values",
    "new_figure",
    "number_format",
    "policy_probs",
    "save_figure",
    "value_norm",
]

#: File formats a figure can be saved in, by suffix.
FORMATS = FIGURE_FORMATS

#: Colour of cells that hold no state (walls) and of unavailable actions.
BLOCKED = "#4d4d4d"


def new_figure(width: float, height: float) -> Figure:
    """A headless figure of the given size in inches, laid out without overlaps."""
    return Figure(figsize=(width, height), layout="constrained", dpi=100)


def save_figure(fig: Figure, path: str | Path, *, dpi: int = 120) -> Path:
    """Write a figure to ``path``: PNG by default, SVG or PDF by the path's suffix.

    A path without a suffix gets ``.png``. Missing parent folders are created.

    Returns:
        The path written.

    Raises:
        InvalidArgumentError: If the suffix names another format.
    """
    p = check_figure_path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=dpi, metadata=_metadata(p))
    return p


def _metadata(p: Path) -> dict[str, Any]:
    # Reproducible files: no creation date in SVG/PDF, a fixed software tag in PNG.
    if p.suffix.lower() == ".png":
        return {"Software": "policylab"}
    return {"Date": None, "Creator": "policylab"}


def check_values(mdp: FiniteMDP, v: ArrayLike, what: str = "v") -> NDArray[np.float64]:
    """Per-state values as an (S,) float array; NaN is allowed (drawn blank).

    Raises:
        ShapeError: If the array does not have one entry per state of the MDP.
        InvalidArgumentError: If an entry is not a number or is infinite.
    """
    arr = check_float_array(v, what, expected=f"an array of numbers, one per state of {mdp.name!r}")
    if arr.shape != (mdp.n_states,):
        raise ShapeError(
            f"{what} has shape {arr.shape}; expected ({mdp.n_states},), one value per state of "
            f"{mdp.name!r} in the order of mdp.states"
        )
    if np.any(np.isinf(arr)):
        s = int(np.flatnonzero(np.isinf(arr))[0])
        raise InvalidArgumentError(f"{what}[{mdp.states[s]!r}] is {arr[s]}; values must be finite")
    return arr


def check_q(mdp: FiniteMDP, q: ArrayLike, what: str = "q") -> NDArray[np.float64]:
    """Action values as an (S, A) float array, NaN where an action is unavailable.

    NaN is allowed anywhere (drawn blank); entries of unavailable actions are ignored
    (the planning layer puts -inf there).

    Raises:
        ShapeError: If the array is not (S, A) for the MDP.
        InvalidArgumentError: If an entry is not a number or is infinite.
    """
    arr = check_float_array(q, what, expected=f"an (S, A) array of numbers for {mdp.name!r}")
    S, A = mdp.n_states, mdp.n_actions
    if arr.shape != (S, A):
        raise ShapeError(
            f"{what} has shape {arr.shape}; expected (S, A) = ({S}, {A}) for {mdp.name!r}"
        )
    # Unavailable actions (and terminal rows) may hold anything, -inf by the planning
    # layer's convention: they are drawn blank.
    arr = np.where(mdp.action_mask, arr, np.nan)
    if np.any(np.isinf(arr)):
        s, a = map(int, np.argwhere(np.isinf(arr))[0])
        raise InvalidArgumentError(
            f"{what}[{mdp.states[s]!r}, {mdp.actions[a]!r}] is {arr[s, a]}; values of available "
            "actions must be finite"
        )
    return arr


def policy_probs(mdp: FiniteMDP, policy: Policy | ArrayLike) -> NDArray[np.float64]:
    """pi(a | s) as an (S, A) array, from a :class:`Policy` of this MDP or an array.

    A boolean (S, A) array is a set of actions per state (such as all optimal actions,
    :func:`policylab.optimal_actions`): the policy uniform over them.

    Raises:
        InvalidPolicyError: If the policy belongs to an MDP with other states or
            actions, or the array is not a valid policy of this MDP.
    """
    if isinstance(policy, Policy):
        if tuple(policy.states) != tuple(mdp.states) or tuple(policy.actions) != tuple(mdp.actions):
            raise InvalidPolicyError(
                f"the policy was built for other states or actions than those of {mdp.name!r} "
                f"({len(policy.states)} states, {len(policy.actions)} actions given; "
                f"{mdp.n_states} states, {mdp.n_actions} actions expected)"
            )
        return np.asarray(policy.probs)
    arr = np.asarray(policy)
    if arr.dtype == np.bool_ and arr.shape == (mdp.n_states, mdp.n_actions):
        counts = arr.sum(axis=1, keepdims=True)
        arr = np.divide(arr, counts, out=np.zeros(arr.shape), where=counts > 0)
    return np.asarray(Policy.from_array(mdp, np.asarray(arr, dtype=np.float64)).probs)


def number_format(values: ArrayLike) -> str:
    """A format for the numbers written in cells: as few decimals as the values need."""
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return "{:.2f}"
    if np.allclose(arr, np.round(arr), atol=1e-9):
        return "{:.0f}"
    top = float(np.max(np.abs(arr)))
    if top >= 100:
        return "{:.0f}"
    if top >= 10:
        return "{:.1f}"
    return "{:.2f}"


def fmt(form: str, x: float) -> str:
    """Format one number with ``form``, writing -0 as 0 and NaN as an empty string."""
    if not np.isfinite(x):
        return ""
    s = form.format(x)
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def value_norm(values: ArrayLike) -> tuple[Normalize, str]:
    """A colour scale for values: diverging around 0 if they change sign, else sequential.

    Returns:
        (norm, colormap name).
    """
    arr = np.asarray(values, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    if arr.size == 0:
        return Normalize(0.0, 1.0), "viridis"
    lo, hi = float(arr.min()), float(arr.max())
    if lo < 0 < hi:
        return TwoSlopeNorm(vcenter=0.0, vmin=lo, vmax=hi), "RdBu"
    if lo == hi:
        lo, hi = lo - 1.0, hi + 1.0
    return Normalize(lo, hi), "viridis"


def cell_text_color(cmap: Colormap, norm: Normalize, value: float) -> str:
    """Black or white, whichever reads better on the colour of ``value``."""
    if not np.isfinite(value):
        return "black"
    r, g, b, _ = cmap(norm(value))
    luminance = 0.299 * r + 0.587 * g + 0.114 * b
    return "black" if luminance > 0.5 else "white"


def is_numeric_labels(labels: Sequence[Any]) -> bool:
    """Whether every label is a real number (numeric actions are plotted as numbers)."""
    return all(
        isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)
        for x in labels
    )


def title_of(mdp: FiniteMDP, what: str, title: str | None) -> str:
    """The figure's title: the caller's, or ``"<what> of <problem>"``."""
    return title if title is not None else f"{what} — {mdp.name} (γ = {mdp.gamma:g})"
