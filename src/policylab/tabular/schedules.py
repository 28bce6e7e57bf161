"""Step-size and exploration schedules, usable from Python and inside numba kernels.

A schedule maps a count n = 1, 2, 3, ... (the n-th visit of a pair, the n-th episode)
to a value: a step size alpha_n or an exploration rate epsilon_n. It is encoded as a
small float64 array ``params = [kind, a, b, c]`` so that compiled kernels evaluate it
with the one function :func:`schedule_value`; :class:`Schedule` is the Python face of
the same array (calling it runs the same compiled function).

Kinds (n counts from 1):

=============  ==================================================  =====================
kind           value at n                                          built by
=============  ==================================================  =====================
constant       a                                                   ``Schedule.constant``
inverse        max(a / n**b, c)   (a = 1, b = 1, c = 0: 1/n)       ``Schedule.inverse``
exponential    max(a * b**(n - 1), c)                              ``Schedule.exponential``
linear         a + (c - a) * min(1, (n - 1) / b)   (a -> c in b)   ``Schedule.linear``
=============  ==================================================  =====================

The step size 1/n makes an incremental update the exact sample average (the notes'
"summation of rewards upon the number of times"); epsilon_k = 1/k over episodes is
GLIE (greedy in the limit with infinite exploration).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.validation import fmt_number

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "CONSTANT",
    "EXPONENTIAL",
    "INVERSE",
    "LINEAR",
    "Schedule",
    "as_schedule",
    "schedule_value",
]

CONSTANT, INVERSE, EXPONENTIAL, LINEAR = 0, 1, 2, 3
_KIND_NAMES = {
    CONSTANT: "constant",
    INVERSE: "inverse",
    EXPONENTIAL: "exponential",
    LINEAR: "linear",
}


@nb.njit(cache=True, nogil=True, inline="always")
def schedule_value(params: NDArray[np.float64], n: float) -> float:  # pragma: no cover - compiled
    """The value of the schedule ``params = [kind, a, b, c]`` at count ``n >= 1``.

    constant: a; inverse: max(a / n**b, c); exponential: max(a * b**(n-1), c);
    linear: a + (c - a) * min(1, (n - 1) / b).
    """
    kind = params[0]  # compared as a float: no conversion in the step loops
    a, b, c = params[1], params[2], params[3]
    if kind == CONSTANT:
        return float(a)
    if n < 1.0:
        n = 1.0
    if kind == INVERSE:
        return float(max(a / n**b, c))
    if kind == EXPONENTIAL:
        return float(max(a * b ** (n - 1.0), c))
    frac = (n - 1.0) / b
    if frac > 1.0:
        frac = 1.0
    return float(a + (c - a) * frac)


@dataclass(frozen=True)
class Schedule:
    """A schedule n -> value (step size or exploration rate); see the module docstring.

    Build one with :meth:`constant`, :meth:`inverse`, :meth:`exponential`,
    :meth:`linear` or :meth:`parse`; ``schedule(n)`` gives its value, ``params`` the
    float64 array a numba kernel reads with :func:`schedule_value`.
    """

    kind: int
    a: float
    b: float = 0.0
    c: float = 0.0

    def __post_init__(self) -> None:
        for name in ("a", "b", "c"):
            x = getattr(self, name)
            if not isinstance(x, (int, float, np.floating, np.integer)) or not math.isfinite(
                float(x)
            ):
                raise InvalidArgumentError(
                    f"schedule parameter {name} must be a finite number; got {fmt_number(x)}"
                )
            object.__setattr__(self, name, float(x))
        if self.kind not in _KIND_NAMES:
            raise InvalidArgumentError(
                f"schedule kind must be one of {sorted(_KIND_NAMES)}; got {self.kind!r}"
            )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def constant(cls, value: float) -> Schedule:
        """The same value at every n (a constant step size alpha, a fixed epsilon)."""
        return cls(CONSTANT, _number(value, "constant value"))

    @classmethod
    def inverse(cls, scale: float = 1.0, power: float = 1.0, floor: float = 0.0) -> Schedule:
        """max(scale / n**power, floor): with the defaults, 1/n (sample average; GLIE)."""
        if not _number(power, "power") > 0.0:
            raise InvalidArgumentError(
                f"inverse schedule power must be > 0 (in (0.5, 1] for step sizes that converge); "
                f"got {fmt_number(power)}"
            )
        scale = _number(scale, "scale")
        if scale < 0:
            raise InvalidArgumentError(
                f"inverse schedule scale must be >= 0 (the value at n = 1); got {fmt_number(scale)}"
            )
        return cls(INVERSE, scale, float(power), _number(floor, "floor"))

    @classmethod
    def exponential(cls, start: float, decay: float, floor: float = 0.0) -> Schedule:
        """max(start * decay**(n - 1), floor), with 0 < decay <= 1."""
        if not 0.0 < _number(decay, "decay") <= 1.0:
            raise InvalidArgumentError(
                f"exponential decay (the second number) must lie in (0, 1] so that the value "
                f"shrinks; got {fmt_number(decay)}"
            )
        return cls(EXPONENTIAL, _number(start, "start"), float(decay), _number(floor, "floor"))

    @classmethod
    def linear(cls, start: float, end: float, steps: float) -> Schedule:
        """From ``start`` at n = 1 straight to ``end`` at n = 1 + steps, then ``end``."""
        if not _number(steps, "steps") > 0:
            raise InvalidArgumentError(
                f"linear schedule steps (the third number: how many counts from start to end) "
                f"must be > 0; got {fmt_number(steps)}"
            )
        return cls(LINEAR, _number(start, "start"), float(steps), _number(end, "end"))

    @classmethod
    def parse(cls, text: str) -> Schedule:
        """A schedule from its command-line spelling.

        ``0.1`` or ``const:0.1`` (constant), ``1/n`` or ``inverse`` or
        ``inverse:SCALE,POWER,FLOOR``, ``exp:START,DECAY[,FLOOR]``,
        ``linear:START,END,STEPS``.

        Raises:
            InvalidArgumentError: If the text is none of these.
        """
        t = str(text).strip().lower().replace(" ", "")
        forms = (
            "expected a number (constant), '1/n', 'inverse:SCALE[,POWER[,FLOOR]]', "
            "'exp:START,DECAY[,FLOOR]' or 'linear:START,END,STEPS'"
        )
        if t in ("1/n", "1/k", "inverse", "glie"):
            return cls.inverse()
        kind, colon, rest = t.partition(":")
        if not colon:
            try:
                value = float(t)
            except ValueError:
                raise InvalidArgumentError(f"cannot read schedule {text!r}; {forms}") from None
            try:
                return cls.constant(value)
            except InvalidArgumentError as e:
                raise InvalidArgumentError(f"schedule {text!r}: {e}") from None
        arity: dict[str, tuple[int, int, Callable[..., Schedule]]] = {
            "const": (1, 1, cls.constant),
            "constant": (1, 1, cls.constant),
            "inverse": (1, 3, cls.inverse),
            "inv": (1, 3, cls.inverse),
            "exp": (2, 3, cls.exponential),
            "exponential": (2, 3, cls.exponential),
            "linear": (3, 3, cls.linear),
            "lin": (3, 3, cls.linear),
        }
        if kind not in arity:
            raise InvalidArgumentError(f"cannot read schedule {text!r}; {forms}")
        lo, hi, build = arity[kind]
        parts = rest.split(",") if rest else []
        if not lo <= len(parts) <= hi:
            count = str(lo) if lo == hi else f"{lo} to {hi}"
            raise InvalidArgumentError(
                f"schedule {text!r} has {len(parts)} number{'' if len(parts) == 1 else 's'}; "
                f"{kind} takes {count} ({forms})"
            )
        nums = []
        for i, x in enumerate(parts, 1):
            try:
                nums.append(float(x))
            except ValueError:
                raise InvalidArgumentError(
                    f"schedule {text!r}: number {i} ({x!r}) is not a number; {forms}"
                ) from None
        try:
            return build(*nums)
        except InvalidArgumentError as e:
            raise InvalidArgumentError(f"schedule {text!r}: {e}") from None

    # ------------------------------------------------------------------ use
    @property
    def params(self) -> NDArray[np.float64]:
        """The ``[kind, a, b, c]`` float64 array that kernels evaluate."""
        return np.array([float(self.kind), self.a, self.b, self.c], dtype=np.float64)

    def __call__(self, n: float) -> float:
        """The value at count ``n`` (n >= 1; smaller n count as 1)."""
        return float(schedule_value(self.params, float(n)))

    def values(self, n: int) -> NDArray[np.float64]:
        """The values at 1, 2, ..., n (for plots and checks)."""
        p = self.params
        return np.array([schedule_value(p, float(k)) for k in range(1, n + 1)])

    def check_range(self, lo: float, hi: float, what: str) -> Schedule:
        """Raise unless every value lies in [lo, hi] (e.g. epsilon in [0, 1])."""
        bounds = [self.a] if self.kind == CONSTANT else [self.a, self.c]
        for x in bounds:
            if not lo <= x <= hi:
                raise InvalidArgumentError(
                    f"{what} must stay in [{lo:g}, {hi:g}]; schedule {self} reaches {fmt_number(x)}"
                )
        return self

    def __str__(self) -> str:
        if self.kind == CONSTANT:
            return f"{self.a:g}"
        if self.kind == INVERSE:
            if self.a == 1.0 and self.b == 1.0 and self.c == 0.0:
                return "1/n"
            return f"inverse:{self.a:g},{self.b:g},{self.c:g}"
        if self.kind == EXPONENTIAL:
            return f"exp:{self.a:g},{self.b:g},{self.c:g}"
        return f"linear:{self.a:g},{self.c:g},{self.b:g}"


def as_schedule(x: Schedule | float | str | None, default: Schedule, what: str) -> Schedule:
    """A :class:`Schedule` from a schedule, a number (constant), a string, or None (default)."""
    if x is None:
        return default
    if isinstance(x, Schedule):
        return x
    if isinstance(x, str):
        return Schedule.parse(x)
    if isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool):
        return Schedule.constant(float(x))
    raise InvalidArgumentError(
        f"{what} must be a number, a Schedule or a schedule string; got {x!r}"
    )


def _number(x: object, what: str) -> float:
    try:
        v = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"schedule {what} must be a number; got {x!r}") from None
    if not math.isfinite(v):
        raise InvalidArgumentError(f"schedule {what} must be finite; got {fmt_number(v)}")
    return v
