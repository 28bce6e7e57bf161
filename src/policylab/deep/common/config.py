"""Configuration dataclasses shared by the Python API and the command line.

Each field is declared with :func:`option`, which keeps its help text; the text appears
in the class docstring (``help(PPOConfig)``), in ``policylab train --help`` and in
error messages. Configs are read from keyword arguments, JSON or TOML files.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
import types
import typing
from pathlib import Path
from typing import Any, TypeVar

from policylab.exceptions import InvalidArgumentError

__all__ = [
    "check_replay_settings",
    "config_from_dict",
    "config_help",
    "documented",
    "load_config_file",
    "option",
]

C = TypeVar("C")


def option(default: Any, help: str) -> Any:
    """A dataclass field with a default and its documentation."""
    if isinstance(default, list | dict):
        return dataclasses.field(
            default_factory=lambda: type(default)(default), metadata={"help": help}
        )
    return dataclasses.field(default=default, metadata={"help": help})


def documented(cls: type[C]) -> type[C]:
    """Append an ``Attributes:`` section, one entry per field, to a config's docstring."""
    lines = [(cls.__doc__ or "").rstrip(), "", "Attributes:"]
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        lines.append(f"    {f.name}: {f.metadata.get('help', '')} (default {_default(f)!r})")
    cls.__doc__ = "\n".join(lines) + "\n"
    return cls


def _default(f: dataclasses.Field[Any]) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def config_help(cls: type[Any]) -> list[tuple[str, str, Any]]:
    """``(name, help, default)`` of every field of a config class."""
    return [(f.name, f.metadata.get("help", ""), _default(f)) for f in dataclasses.fields(cls)]


def _coerce(name: str, value: Any, tp: Any) -> Any:
    """``value`` as the field's type, or an error naming the field."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _coerce(name, value, a)
            except InvalidArgumentError as e:
                errors.append(str(e))
        raise InvalidArgumentError(errors[0] if errors else f"{name}: bad value {value!r}")
    if origin in (tuple, list):
        if not isinstance(value, list | tuple):
            raise InvalidArgumentError(f"config field {name!r} must be a list; got {value!r}")
        item = args[0] if args else Any
        return tuple(_coerce(name, v, item) for v in value)
    if tp is bool:
        if not isinstance(value, bool):
            raise InvalidArgumentError(
                f"config field {name!r} must be true or false; got {value!r}"
            )
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int | float) or int(value) != value:
            raise InvalidArgumentError(f"config field {name!r} must be an integer; got {value!r}")
        return int(value)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InvalidArgumentError(f"config field {name!r} must be a number; got {value!r}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise InvalidArgumentError(f"config field {name!r} must be a string; got {value!r}")
        return value
    return value


def config_from_dict(cls: type[C], values: dict[str, Any], base: C | None = None) -> C:
    """A config of class ``cls`` from ``values`` (over ``base`` or the defaults), validated.

    Raises:
        InvalidArgumentError: On an unknown field name or a value of the wrong type or range.
    """
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(values) - set(fields))
    if unknown:
        raise InvalidArgumentError(
            f"unknown {cls.__name__} field(s) {', '.join(map(repr, unknown))}; known fields: "
            f"{', '.join(sorted(fields))}"
        )
    hints = typing.get_type_hints(cls)
    coerced = {k: _coerce(k, v, hints[k]) for k, v in values.items()}
    cfg = dataclasses.replace(base, **coerced) if base is not None else cls(**coerced)  # type: ignore[type-var]
    validate = getattr(cfg, "validate", None)
    if validate is not None:
        validate()
    return cfg


def load_config_file(path: str | Path) -> dict[str, Any]:
    """The key/value table of a JSON or TOML config file.

    Raises:
        InvalidArgumentError: If the file is missing, unparsable, or not a table.
    """
    p = Path(path)
    if not p.is_file():
        raise InvalidArgumentError(f"config file {str(p)!r} does not exist")
    try:
        if p.suffix.lower() == ".toml":
            data: Any = tomllib.loads(p.read_text())
        else:
            data = json.loads(p.read_text())
    except (json.JSONDecodeError, tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise InvalidArgumentError(f"config file {str(p)!r} is not valid JSON/TOML: {e}") from None
    if not isinstance(data, dict):
        raise InvalidArgumentError(f"config file {str(p)!r} must hold one table of field = value")
    return data


def check(cond: bool, message: str) -> None:
    """Raise :class:`InvalidArgumentError` with ``message`` unless ``cond``."""
    if not cond:
        raise InvalidArgumentError(message)


def check_replay_settings(cfg: Any) -> None:
    """The range checks every replay-based learner shares (DQN, SAC, TD3).

    Checks ``buffer_size``, ``batch_size``, ``learning_starts``, ``train_freq``,
    ``gradient_steps`` and ``tau`` (the Polyak weight, in (0, 1]).

    Raises:
        InvalidArgumentError: Naming the first field out of range and its value.
    """
    check(cfg.buffer_size >= 1, f"buffer_size must be >= 1; got {cfg.buffer_size}")
    check(cfg.batch_size >= 1, f"batch_size must be >= 1; got {cfg.batch_size}")
    check(cfg.learning_starts >= 0, f"learning_starts must be >= 0; got {cfg.learning_starts}")
    check(cfg.train_freq >= 1, f"train_freq must be >= 1; got {cfg.train_freq}")
    check(cfg.gradient_steps >= 0, f"gradient_steps must be >= 0; got {cfg.gradient_steps}")
    check(0.0 < cfg.tau <= 1.0, f"tau must be in (0, 1]; got {cfg.tau}")
