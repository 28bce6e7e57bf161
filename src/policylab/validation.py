"""Checks of user input, written once and used by every entry point (API and CLI).

Every check returns the value in its canonical type, or raises a policylab error
(:class:`~policylab.exceptions.InvalidArgumentError` unless said otherwise) whose
message names the argument, what was expected and what was given, with numbers
written so that the problem is visible (``fmt_number``), never as ``np.float64(...)``.

The CLI maps these errors to exit code 2 with the message on one line, so a value
checked here gets the same words whether it came from Python or the command line.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError, PolicylabError, ShapeError

__all__ = [
    "FIGURE_FORMATS",
    "MAX_SEED",
    "Seed",
    "as_generator",
    "check_choice",
    "check_count",
    "check_figure_path",
    "check_float_array",
    "check_fraction",
    "check_gamma",
    "check_generator",
    "check_int",
    "check_number",
    "check_output_dir",
    "check_output_file",
    "check_positive",
    "check_seed",
    "did_you_mean",
    "fmt_number",
    "normalize_name",
]

Seed = int | np.random.Generator | None
"""What every stochastic function takes: an int seed, a Generator, or None (fresh entropy)."""

MAX_SEED = 2**63 - 1
"""Largest seed accepted (NumPy's ``SeedSequence`` takes any non-negative int; numba's
RNG state and torch's ``manual_seed`` take 64-bit values)."""


def fmt_number(x: Any, near: float | None = None) -> str:
    """A number as a user should read it in a message.

    Floats get the shortest form that round-trips (``repr`` of a Python float), so
    ``1 + 3e-8`` shows as ``1.00000003`` rather than ``1``; NumPy scalars are written
    like Python numbers (``-0.5``, not ``np.float64(-0.5)``); anything else uses ``repr``.

    Args:
        x: The number.
        near: A value ``x`` is compared with (a sum that should be 1): then ``x`` gets
            just enough significant digits (at least 6) to tell it from ``near``, so
            ``0.93`` stays ``0.93`` and ``1.00000003`` keeps its last digit.
    """
    if isinstance(x, bool | np.bool_):
        return str(bool(x))
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        v = float(x)
        if near is None or not math.isfinite(v) or v == near:
            return repr(v)
        rel = abs(v - near) / max(abs(v), abs(near))
        digits = min(17, max(6, math.ceil(-math.log10(rel)) + 2)) if rel > 0 else 17
        return f"{v:.{digits}g}"
    return repr(x)


def normalize_name(name: str) -> str:
    """The canonical spelling of a registry name: stripped, lower case, ``-`` for ``_``.

    ``"Q_Learning "`` and ``"q-learning"`` name the same algorithm; every registry
    (problems, algorithms) looks names up through this one function.
    """
    return name.strip().lower().replace("_", "-")


def did_you_mean(given: str, known: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``known`` to ``given``, or ``""``."""
    import difflib

    close = difflib.get_close_matches(given, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def check_choice(value: Any, choices: Iterable[str], name: str) -> str:
    """One of a fixed set of names, compared after :func:`normalize_name`.

    Returns:
        The matching entry of ``choices``.

    Raises:
        InvalidArgumentError: Listing the choices, with the closest one suggested.
    """
    known = list(choices)
    if not isinstance(value, str):
        raise InvalidArgumentError(
            f"{name} must be one of {', '.join(known)}; got {type(value).__name__} {value!r}"
        )
    by_key = {normalize_name(c): c for c in known}
    key = normalize_name(value)
    if key in by_key:
        return by_key[key]
    raise InvalidArgumentError(
        f"{name} must be one of {', '.join(known)}; got {value!r}{did_you_mean(key, by_key)}"
    )


def check_number(
    value: Any,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """A finite real number within optional bounds.

    Args:
        value: What the user gave.
        name: The argument's name, as the user knows it (``"alpha"``, ``"--alpha"``).
        low: Lower bound (inclusive unless ``low_open``).
        high: Upper bound (inclusive unless ``high_open``).
        low_open: Exclude ``low`` itself.
        high_open: Exclude ``high`` itself.

    Returns:
        The value as a Python float.

    Raises:
        InvalidArgumentError: Not a number, not finite, or out of bounds.
    """
    if isinstance(value, bool | np.bool_ | str | bytes):
        raise InvalidArgumentError(f"{name} must be a number; got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidArgumentError(
            f"{name} must be a number; got {type(value).__name__} {value!r}"
        ) from None
    if not math.isfinite(x):
        raise InvalidArgumentError(f"{name} must be a finite number; got {fmt_number(x)}")
    lo_bad = low is not None and (x <= low if low_open else x < low)
    hi_bad = high is not None and (x >= high if high_open else x > high)
    if lo_bad or hi_bad:
        given = value if isinstance(value, int | np.integer | float | np.floating) else x
        raise InvalidArgumentError(
            f"{name} must be {_interval(low, high, low_open, high_open)}; got {fmt_number(given)}"
        )
    return x


def _bound(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else fmt_number(x)


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    if low is not None and high is not None:
        return (
            f"in {'(' if low_open else '['}{_bound(low)}, {_bound(high)}{')' if high_open else ']'}"
        )
    if low is not None:
        return f"{'>' if low_open else '>='} {_bound(low)}"
    assert high is not None
    return f"{'<' if high_open else '<='} {_bound(high)}"


def check_positive(value: Any, name: str) -> float:
    """A finite number > 0 (a tolerance, a learning rate, a temperature)."""
    return check_number(value, name, low=0.0, low_open=True)


def check_fraction(value: Any, name: str) -> float:
    """A number in [0, 1] (a probability, lambda, epsilon)."""
    return check_number(value, name, low=0.0, high=1.0)


def check_gamma(value: Any, default: float | None = None, name: str = "gamma") -> float:
    """The discount rate: ``value`` checked to lie in [0, 1], or ``default`` if ``value`` is None.

    Raises:
        InvalidArgumentError: ``value`` is not a number in [0, 1], or both are None.
    """
    if value is None:
        if default is None:
            raise InvalidArgumentError(f"{name} must be given (a number in [0, 1])")
        return float(default)
    return check_fraction(value, name)


def check_int(
    value: Any, name: str, *, minimum: int | None = None, maximum: int | None = None
) -> int:
    """An integer (Python or NumPy; bools and floats refused) within optional bounds."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise InvalidArgumentError(
            f"{name} must be an integer; got {type(value).__name__} {value!r}"
        )
    v = int(value)
    if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
        if maximum is None or (minimum is not None and v < minimum):
            bound = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        elif minimum is None:
            bound = f"an integer <= {_int_text(maximum)}"
        else:
            bound = f"an integer in [{minimum}, {_int_text(maximum)}]"
        raise InvalidArgumentError(f"{name} must be {bound}; got {v}")
    return v


def _int_text(n: int) -> str:
    """A bound as a user reads it: ``2**62`` rather than 4611686018427387904."""
    for k in range(31, 64):
        if n == 2**k:
            return f"2**{k}"
        if n == 2**k - 1:
            return f"2**{k} - 1"
    return str(n)


def check_count(value: Any, name: str, minimum: int = 1, maximum: int | None = None) -> int:
    """A count: an integer >= ``minimum`` (episodes, steps, seeds, n, planning steps)."""
    return check_int(value, name, minimum=minimum, maximum=maximum)


def check_seed(value: Any, name: str = "seed") -> int | None:
    """A seed: None (fresh entropy) or an integer in [0, 2**63 - 1].

    A ``numpy.random.Generator`` is not a seed for this check; functions that accept
    one test for it before calling this.
    """
    if value is None:
        return None
    v = check_int(value, name)
    if not 0 <= v <= MAX_SEED:
        raise InvalidArgumentError(f"{name} must be a non-negative integer below 2**63; got {v}")
    return v


def check_float_array(
    value: Any,
    name: str,
    *,
    expected: str = "an array of real numbers",
    error: type[PolicylabError] = InvalidArgumentError,
) -> np.ndarray[Any, np.dtype[np.float64]]:
    """An array of real numbers as float64 (bools and integers too), never NumPy's error.

    Strings (even ``"0.5"``), complex numbers and other objects are refused, and nested
    lists of different lengths give a :class:`~policylab.exceptions.ShapeError`.

    Args:
        value: What the user gave.
        name: The argument's name in messages.
        expected: What it should be, for the message.
        error: The error type to raise (a policylab error the caller documents).
    """
    try:
        arr = np.asarray(value)
    except ValueError:  # ragged nested lists
        raise ShapeError(
            f"{name} has rows of different lengths; expected a rectangular array"
        ) from None
    if arr.dtype.kind in "biuf":
        return arr.astype(np.float64)
    if arr.dtype.kind == "O":
        try:
            return np.asarray(arr, dtype=np.float64)
        except (TypeError, ValueError):
            pass
    first = f" (first entry {arr.ravel()[:1].tolist()[0]!r})" if arr.size else ""
    raise error(f"{name} must be {expected}; got an array of dtype {arr.dtype}{first}")


def as_generator(seed: Any, name: str = "seed") -> np.random.Generator:
    """The random generator of a stochastic function: a Generator as given, else a new one.

    Args:
        seed: A ``numpy.random.Generator`` (used as it is), an integer in [0, 2**63 - 1],
            or None (fresh entropy).
        name: The argument's name in messages.

    Raises:
        InvalidArgumentError: Anything else (a negative or float seed, a string).
    """
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(check_seed(seed, name))


def check_generator(
    rng: Any, name: str = "rng", error: type[PolicylabError] = InvalidArgumentError
) -> np.random.Generator:
    """A ``numpy.random.Generator`` (what low-level sampling methods draw from)."""
    if not isinstance(rng, np.random.Generator):
        raise error(f"{name} must be a numpy.random.Generator; got {type(rng).__name__}")
    return rng


def check_output_file(path: str | Path, name: str, suffixes: Iterable[str] | None = None) -> Path:
    """A file path that can be written: checked before any work is done.

    The parent folder must exist or be creatable, and be writable; the path must not be
    a folder; its suffix, when ``suffixes`` is given, must be one of them.

    Raises:
        InvalidArgumentError: Naming the path and what is wrong with it.
    """
    p = Path(path)
    if suffixes is not None:
        allowed = sorted({s.lower() for s in suffixes})
        if p.suffix.lower() not in allowed:
            raise InvalidArgumentError(
                f"{name} {str(p)!r} has suffix {p.suffix or '(none)'!r}; expected one of "
                f"{', '.join(allowed)}"
            )
    if p.is_dir():
        raise InvalidArgumentError(f"{name} {str(p)!r} is a folder; expected a file name")
    _check_writable_parent(p.parent, name, p)
    return p


FIGURE_FORMATS = (".png", ".svg", ".pdf")
"""File formats a figure can be saved in, by suffix (a path without one gets ``.png``)."""


def check_figure_path(path: str | Path, name: str = "figure path") -> Path:
    """Where a figure will be written, checked before the work that draws it.

    A path without a suffix gets ``.png``; otherwise the suffix must be one of
    :data:`FIGURE_FORMATS`; the file must be writable (see :func:`check_output_file`).

    Returns:
        The path the figure will have.

    Raises:
        InvalidArgumentError: Unknown suffix, a folder, or a place that cannot be written.
    """
    p = Path(path)
    if p.is_dir():
        raise InvalidArgumentError(f"{name} {str(p)!r} is a folder; expected a file name")
    if p.suffix == "":
        p = p.with_suffix(".png")
    elif p.suffix.lower() not in FIGURE_FORMATS:
        raise InvalidArgumentError(
            f"{name} {str(path)!r} ends in {p.suffix!r}; expected one of "
            f"{', '.join(FIGURE_FORMATS)} (or no suffix for PNG)"
        )
    return check_output_file(p, name)


def check_output_dir(path: str | Path, name: str) -> Path:
    """A folder that can be created or written into (it need not exist yet).

    Raises:
        InvalidArgumentError: The path is an existing file, or cannot be created or written.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise InvalidArgumentError(f"{name} {str(p)!r} is an existing file; expected a folder")
    _check_writable_parent(p if p.is_dir() else p.parent, name, p)
    return p


def _check_writable_parent(parent: Path, name: str, target: Path) -> None:
    """The nearest existing ancestor of ``parent`` is a writable folder."""
    anc = parent if str(parent) else Path(".")
    while not anc.exists():
        if anc.parent == anc:
            break
        anc = anc.parent
    if not anc.is_dir():
        raise InvalidArgumentError(f"{name} {str(target)!r}: {str(anc)!r} is not a folder")
    try:  # access() says yes to root on read-only or virtual file systems: try for real
        with tempfile.TemporaryFile(dir=anc, prefix=".policylab-write-check-"):
            pass
    except OSError as exc:
        raise InvalidArgumentError(
            f"{name} {str(target)!r} cannot be written: no file can be created in "
            f"{str(anc)!r} ({exc.strerror or exc})"
        ) from None
