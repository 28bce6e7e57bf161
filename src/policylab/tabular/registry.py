"""The registry of tabular algorithms that ``policylab learn ALGO PROBLEM`` reads.

An algorithm registers its learner function once, with its command-line options; the
``learn`` command builds one subcommand per registered algorithm, so adding an
algorithm never means editing the command. See :mod:`policylab.tabular` for the steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from policylab.exceptions import InvalidArgumentError
from policylab.validation import did_you_mean, normalize_name

if TYPE_CHECKING:
    from policylab.tabular.result import LearnResult

__all__ = ["AlgorithmSpec", "Option", "algorithm", "list_algorithms", "register_algorithm"]

OptionKind = Literal["flag", "float", "int", "schedule", "str", "policy"]


@dataclass(frozen=True)
class Option:
    """One algorithm-specific command-line option.

    Attributes:
        flag: The option as typed, ``"--every-visit"``.
        param: The learner's keyword argument it sets, ``"first_visit"``.
        kind: ``"flag"`` (a switch), ``"float"``, ``"int"``, ``"str"``, ``"schedule"``
            (a number or a schedule spelling such as ``1/n`` or ``exp:1,0.999,0.05``,
            see :meth:`~policylab.tabular.Schedule.parse`) or ``"policy"`` (the name of
            one of the problem's registered policies, or ``uniform``).
        help: The ``--help`` text.
        default: The value when the option is not given (None: the learner's default).
        value_if_set: For a flag: the keyword's value when the flag is given (``False``
            for ``--every-visit`` setting ``first_visit``); default True.
        annotation: The learner parameter's type as written in its signature
            (``"int"``); empty where the learner is written by hand.
        value: The learner parameter's default as written in its signature (``"4"``).
        doc: The learner's ``Args:`` text for the parameter (default: ``help``).
    """

    flag: str
    param: str
    kind: OptionKind
    help: str
    default: Any = None
    value_if_set: Any = True
    annotation: str = ""
    value: str = ""
    doc: str = ""


@dataclass(frozen=True)
class AlgorithmSpec:
    """A registered tabular algorithm.

    Attributes:
        name: Command-line name (``"mc-prediction"``).
        learner: ``learner(problem, *, episodes, seed, gamma, progress, **options)``
            returning a :class:`~policylab.tabular.LearnResult`; ``problem`` is a
            FiniteMDP (fast compiled path) or a Gymnasium env (general path).
        description: One line for ``policylab learn --help``.
        options: The algorithm's own command-line options.
        kind: ``"prediction"`` (evaluates a given policy; the CLI adds ``--policy``)
            or ``"control"``.
        default_episodes: Episodes when ``--episodes`` is not given.
    """

    name: str
    learner: Callable[..., LearnResult]
    description: str
    options: tuple[Option, ...] = field(default_factory=tuple)
    kind: Literal["prediction", "control"] = "control"
    default_episodes: int = 10_000


_ALGORITHMS: dict[str, AlgorithmSpec] = {}


def register_algorithm(
    name: str,
    learner: Callable[..., LearnResult],
    description: str,
    *,
    options: tuple[Option, ...] | list[Option] = (),
    kind: Literal["prediction", "control"] = "control",
    default_episodes: int = 10_000,
) -> AlgorithmSpec:
    """Register a tabular algorithm under a command-line name (lowercase, hyphens)."""
    key = name.strip().lower()
    if not key or " " in key or "_" in key:
        raise InvalidArgumentError(
            f"algorithm names are lowercase words joined by hyphens; got {name!r}"
        )
    spec = AlgorithmSpec(key, learner, description, tuple(options), kind, default_episodes)
    _ALGORITHMS[key] = spec
    return spec


def algorithm(name: str) -> AlgorithmSpec:
    """The spec of a registered algorithm.

    Raises:
        InvalidArgumentError: Naming the registered algorithms.
    """
    import policylab.tabular  # noqa: F401  (registers the built-in algorithms)

    key = normalize_name(name)
    if key not in _ALGORITHMS:
        raise InvalidArgumentError(
            f"unknown algorithm {name!r}{did_you_mean(key, _ALGORITHMS)}; known algorithms: "
            f"{', '.join(sorted(_ALGORITHMS))}"
        )
    return _ALGORITHMS[key]


def list_algorithms() -> list[AlgorithmSpec]:
    """Every registered algorithm, sorted by name."""
    import policylab.tabular  # noqa: F401

    return [_ALGORITHMS[k] for k in sorted(_ALGORITHMS)]
