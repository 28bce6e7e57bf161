"""The registry of built-in problems, shared by the API, the CLI and the Gymnasium ids.

A problem is registered once with its builder; the command line names it by the
builder's name with hyphens (``recycling_robot`` -> ``recycling-robot``) and Gymnasium
knows it as ``policylab/<CamelName>-v0``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from policylab.exceptions import UnknownProblemError
from policylab.validation import did_you_mean, normalize_name

if TYPE_CHECKING:
    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = [
    "ProblemSpec",
    "find_problem",
    "get_problem",
    "list_problems",
    "problem",
    "problem_names",
    "register_problem",
    "unknown_problem_message",
]


@dataclass(frozen=True)
class ProblemSpec:
    """A registered built-in problem.

    Attributes:
        name: Command-line name (hyphens).
        builder: Function returning the :class:`FiniteMDP` (keyword parameters allowed).
        description: One line for ``policylab problems``.
        policies: Named policies of the problem: name -> function of the MDP.
        max_episode_steps: Step limit of its Gymnasium env (needed by continuing tasks).
        section: Where the problem comes from (notes section or textbook example).
    """

    name: str
    builder: Callable[..., FiniteMDP]
    description: str
    policies: dict[str, Callable[[FiniteMDP], Policy]] = field(default_factory=dict)
    max_episode_steps: int | None = None
    section: str = ""

    @property
    def gym_id(self) -> str:
        """The Gymnasium id, ``policylab/<CamelName>-v0``."""
        camel = "".join(part.capitalize() for part in self.name.split("-"))
        return f"policylab/{camel}-v0"


_REGISTRY: dict[str, ProblemSpec] = {}


def register_problem(
    builder: Callable[..., FiniteMDP],
    description: str,
    *,
    policies: dict[str, Callable[[FiniteMDP], Policy]] | None = None,
    max_episode_steps: int | None = None,
    section: str = "",
) -> ProblemSpec:
    """Register a built-in problem under its builder's name with hyphens."""
    name = builder.__name__.replace("_", "-")
    spec = ProblemSpec(name, builder, description, dict(policies or {}), max_episode_steps, section)
    _REGISTRY[name] = spec
    return spec


def find_problem(name: str) -> ProblemSpec | None:
    """The spec of a registered problem under any spelling of its name, or None.

    ``"Recycling_Robot"`` finds ``recycling-robot`` (see
    :func:`policylab.validation.normalize_name`).
    """
    return _REGISTRY.get(normalize_name(name)) if isinstance(name, str) else None


def problem_names() -> list[str]:
    """The names of every registered problem, sorted."""
    return sorted(_REGISTRY)


def unknown_problem_message(name: str, extra: str = "") -> str:
    """The one message for a problem name that is not registered: the closest name, the list."""
    hint = did_you_mean(normalize_name(name), _REGISTRY) if isinstance(name, str) else ""
    return f"unknown problem {name!r}{hint}; known problems: {', '.join(problem_names())}{extra}"


def problem(name: str) -> ProblemSpec:
    """The spec of a registered problem.

    Raises:
        UnknownProblemError: With the closest name and the list of known names.
    """
    spec = find_problem(name)
    if spec is None:
        raise UnknownProblemError(unknown_problem_message(name))
    return spec


def get_problem(name: str, **kwargs: Any) -> FiniteMDP:
    """Build a registered problem by name, passing keyword arguments to its builder.

    Raises:
        UnknownProblemError: An unknown name.
        InvalidArgumentError: A keyword the builder does not take (the message lists those
            it takes).
    """
    import inspect

    from policylab.exceptions import InvalidArgumentError

    spec = problem(name)
    sig = inspect.signature(spec.builder)
    try:
        sig.bind(**kwargs)
    except TypeError:
        unknown = sorted(set(kwargs) - set(sig.parameters))
        raise InvalidArgumentError(
            f"problem {spec.name!r} takes no parameter {', '.join(map(repr, unknown))}; its "
            f"parameters are: {', '.join(sig.parameters) or '(none)'}"
        ) from None
    return spec.builder(**kwargs)


def list_problems() -> list[ProblemSpec]:
    """Every registered problem, sorted by name."""
    return [_REGISTRY[k] for k in problem_names()]
