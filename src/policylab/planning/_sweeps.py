"""The sweep loop and the sup-norm stopping rule shared by every iterative solver."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from policylab.exceptions import NotConvergedWarning

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["SweepOutcome", "run_sweeps", "span_bounds"]


def span_bounds(d: NDArray[np.float64], gamma: float, has_terminal: bool) -> tuple[float, float]:
    """MacQueen's bounds from one synchronous sweep d = T v - v (gamma < 1).

    For a monotone operator T with T(v + c 1) = T v + gamma c 1 (both Bellman
    operators), the fixed point v_T satisfies, in every non-terminal state,

        T v + gamma / (1 - gamma) * min_s d(s) <= v_T <= T v + gamma / (1 - gamma) * max_s d(s),

    (d taken as 0 on terminal states when there are any). Returning the midpoint
    T v + gamma / (1 - gamma) * (min d + max d) / 2 is therefore within
    gamma / (1 - gamma) * (max d - min d) / 2 of v_T in the sup norm.

    Returns:
        ``(shift, bound)``: the constant to add to T v, and the sup-norm error bound.
    """
    lo, hi = float(d.min()), float(d.max())
    if has_terminal:
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    k = gamma / (1.0 - gamma)
    return k * (lo + hi) / 2.0, k * (hi - lo) / 2.0


@dataclass
class SweepOutcome:
    """The end state of :func:`run_sweeps`."""

    v: NDArray[np.float64]
    iterations: int
    converged: bool
    history: NDArray[np.float64]
    residual: float
    error_bound: float | None
    seconds: float


def run_sweeps(
    *,
    synchronous: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None,
    in_place: Callable[[NDArray[np.float64]], float] | None,
    v0: NDArray[np.float64],
    live: NDArray[np.bool_],
    gamma: float,
    tol: float,
    max_iter: int,
    what: str,
) -> SweepOutcome:
    """Iterate a Bellman operator until its fixed point is known to within ``tol``.

    Exactly one of ``synchronous`` (v -> T v, a new array) and ``in_place`` (updates v,
    returns max |change|) is given.

    Stopping rule, gamma < 1: synchronous sweeps stop when MacQueen's bound
    (:func:`span_bounds`) is <= ``tol`` and return the midpoint estimate; in-place
    sweeps, whose operator is also a gamma-contraction in the sup norm, stop when
    gamma / (1 - gamma) * max_s |v_{k+1}(s) - v_k(s)| <= ``tol``, which bounds
    max_s |v_{k+1}(s) - v_T(s)|. Either way ``error_bound`` <= ``tol`` is proven.
    gamma = 1: no such bound exists; sweeps stop when max_s |change| <= ``tol`` and
    ``error_bound`` is None.

    Warns:
        NotConvergedWarning: If ``max_iter`` sweeps end before the rule is met.
    """
    t0 = time.perf_counter()
    v = v0.copy()
    has_terminal = not bool(live.all())
    history: list[float] = []
    converged = False
    bound: float | None = None
    residual = np.inf
    for _ in range(max_iter):
        if in_place is not None:
            residual = in_place(v)
            history.append(residual)
            if gamma < 1.0:
                bound = gamma / (1.0 - gamma) * residual
                converged = bound <= tol
            else:
                converged = residual <= tol
        else:
            assert synchronous is not None
            tv = synchronous(v)
            d = tv - v
            residual = float(np.abs(d).max()) if d.size else 0.0
            history.append(residual)
            if gamma < 1.0:
                shift, bound = span_bounds(d[live], gamma, has_terminal)
                if bound <= tol:
                    tv[live] += shift
                    converged = True
                else:  # no shift applied: T v is within max(|lo|, |hi|) * gamma/(1-gamma)
                    bound = abs(shift) + bound
            else:
                converged = residual <= tol
            v = tv
        if not np.isfinite(residual):
            break
        if converged:
            break
    if not converged:
        warnings.warn(
            f"{what} stopped after {len(history)} sweeps (max_iter) before converging: last "
            f"change {residual:.3g}"
            + (f", error bound {bound:.3g}" if bound is not None else "")
            + f" > tol {tol:g}",
            NotConvergedWarning,
            stacklevel=3,
        )
    return SweepOutcome(
        v=v,
        iterations=len(history),
        converged=converged,
        history=np.asarray(history),
        residual=float(residual),
        error_bound=bound if gamma < 1.0 else None,
        seconds=time.perf_counter() - t0,
    )
