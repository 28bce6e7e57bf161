"""What one experiment (a sweep or a tuning run) is: its algorithm, problem, seeds, options.

An :class:`ExperimentSpec` is plain data (JSON-ready): it is written into the sweep
folder's ``sweep.json`` so that ``--resume`` rebuilds the same experiment, and it is
handed to every trial. This module parses and checks everything a user gives before any
trial starts (an unknown option, a ``--set`` key that is not a field, a bad value, a bad
distribution), so a mistake is refused at once with its name, not after minutes of work.
Nothing here imports Ray.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from policylab.exceptions import InvalidArgumentError
from policylab.validation import check_count, check_seed, did_you_mean, normalize_name

__all__ = [
    "DEEP_ALGORITHMS",
    "ExperimentSpec",
    "config_label",
    "family_of",
    "parse_distribution",
    "parse_option_tokens",
    "parse_set",
]

#: The deep RL algorithms ``policylab train`` runs (each (configuration, seed) is one trial).
DEEP_ALGORITHMS = ("dqn", "ppo", "sac", "td3")

#: Tabular options every learner takes (``policylab learn``'s common options).
_TABULAR_COMMON: dict[str, tuple[str, str]] = {
    "--episodes": ("episodes", "int"),
    "--gamma": ("gamma", "float"),
    "--max-steps": ("max_steps", "int"),
}
_DEEP_COMMON: dict[str, tuple[str, str]] = {"--steps": ("steps", "int")}

Family = Literal["tabular", "deep"]


def family_of(algorithm: str) -> tuple[str, Family]:
    """(normalized name, ``"tabular"`` or ``"deep"``) of an algorithm name.

    Raises:
        InvalidArgumentError: An unknown algorithm, naming the known ones.
    """
    from policylab.tabular.registry import list_algorithms

    name = normalize_name(algorithm)
    if name in DEEP_ALGORITHMS:
        return name, "deep"
    tabular = [s.name for s in list_algorithms()]
    if name in tabular:
        return name, "tabular"
    known = sorted([*tabular, *DEEP_ALGORITHMS])
    raise InvalidArgumentError(
        f"unknown algorithm {algorithm!r}{did_you_mean(name, known)}; known algorithms: "
        f"{', '.join(known)}"
    )


def _tabular_options(name: str) -> dict[str, tuple[str, str]]:
    """``{flag: (param, kind)}`` of a tabular algorithm, as ``policylab learn`` takes them."""
    from policylab.tabular.registry import algorithm

    spec = algorithm(name)
    out = dict(_TABULAR_COMMON)
    if spec.kind == "prediction":
        out["--policy"] = ("policy", "policy")
    for opt in spec.options:
        out[opt.flag] = (opt.param, opt.kind)
    return out


def _deep_fields(name: str) -> dict[str, Any]:
    """``{field: dataclass field}`` of a deep algorithm's config class."""
    from policylab.deep.zoo import ALGORITHMS

    cls = ALGORITHMS[name].config_class
    return {f.name: f for f in dataclasses.fields(cls)}


def _convert(value: Any, kind: str, where: str) -> Any:
    """A tabular option's value as JSON-ready data of its kind (checked, not yet built)."""
    if kind == "flag":
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in ("true", "1", "yes", "on"):
            return True
        if text in ("false", "0", "no", "off"):
            return False
        raise InvalidArgumentError(f"{where} is a switch: true or false; got {value!r}")
    if kind == "int":
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise InvalidArgumentError(f"{where} must be an integer; got {value!r}") from None
        if not math.isfinite(f) or f != int(f):
            raise InvalidArgumentError(f"{where} must be an integer; got {value!r}")
        return int(f)
    if kind == "float":
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise InvalidArgumentError(f"{where} must be a number; got {value!r}") from None
        if not math.isfinite(f):
            raise InvalidArgumentError(f"{where} must be a finite number; got {value!r}")
        return f
    if kind == "schedule":
        from policylab.tabular.schedules import Schedule

        try:
            as_number = float(value)
        except (TypeError, ValueError):
            as_number = None
        try:
            Schedule.parse(str(value))
        except InvalidArgumentError as e:
            raise InvalidArgumentError(f"{where}: {e}") from None
        return as_number if as_number is not None and math.isfinite(as_number) else str(value)
    return str(value)


def parse_option_tokens(algorithm: str, tokens: list[str]) -> dict[str, Any]:
    """The algorithm's own options given on the command line, as ``{param: value}``.

    Tabular algorithms take ``policylab learn``'s options (``--episodes``, ``--gamma``,
    ``--max-steps``, and their own such as ``--alpha``); deep algorithms take
    ``--steps`` (config fields go through ``--set``).

    Raises:
        InvalidArgumentError: An unknown option (with a suggestion) or a bad value.
    """
    name, family = family_of(algorithm)
    known = _tabular_options(name) if family == "tabular" else dict(_DEEP_COMMON)
    out: dict[str, Any] = {}
    i = 0
    while i < len(tokens):
        tok = tokens[i]
        flag, eq, inline = tok.partition("=")
        if flag == "--seed":
            raise InvalidArgumentError("the seeds of a sweep are set by --seeds N (seeds 0..N-1)")
        if flag not in known:
            what = "option" if tok.startswith("-") else "argument"
            raise InvalidArgumentError(
                f"unknown {what} {tok!r} for {name}{did_you_mean(flag, known)}; its options: "
                f"{', '.join(sorted(known))}"
            )
        param, kind = known[flag]
        if kind == "flag" and not eq:
            out[param] = True
            i += 1
            continue
        if eq:
            value: Any = inline
            i += 1
        else:
            if i + 1 >= len(tokens):
                raise InvalidArgumentError(f"option {flag} needs a value")
            value = tokens[i + 1]
            i += 2
        out[param] = _convert(value, kind, flag)
    return out


def parse_set(items: list[str]) -> dict[str, list[Any]]:
    """``--set KEY=V1,V2,...`` items as ``{key: [values]}`` (values parsed as JSON if they are).

    Raises:
        InvalidArgumentError: An item without ``=``, an empty value, or a key given twice.
    """
    out: dict[str, list[Any]] = {}
    for item in items:
        key, eq, values = item.partition("=")
        key = key.strip()
        if not eq or not key or not values.strip():
            raise InvalidArgumentError(f"--set takes KEY=V1,V2,...; got {item!r}")
        if key in out:
            raise InvalidArgumentError(f"--set {key} is given twice; list its values once")
        parsed: list[Any] = []
        for v in values.split(","):
            v = v.strip()
            try:
                parsed.append(json.loads(v))
            except json.JSONDecodeError:
                parsed.append(v)
        out[key] = parsed
    return out


_DISTRIBUTIONS = ("choice", "int", "loguniform", "uniform")


def parse_distribution(item: str) -> tuple[str, dict[str, Any]]:
    """``NAME=DIST`` of ``--param`` as ``(name, {"kind", "low", "high"} or {"kind", "values"})``.

    DIST is ``loguniform:LOW,HIGH``, ``uniform:LOW,HIGH``, ``int:LOW,HIGH`` (both ends
    included) or ``choice:A,B,C``.

    Raises:
        InvalidArgumentError: A malformed item, an unknown kind, or empty/reversed bounds.
    """
    name, eq, dist = item.partition("=")
    name = name.strip()
    kind, colon, args = dist.partition(":")
    kind = kind.strip().lower()
    if not eq or not name or not colon:
        raise InvalidArgumentError(
            f"--param takes NAME=DIST with DIST one of loguniform:LOW,HIGH, uniform:LOW,HIGH, "
            f"int:LOW,HIGH, choice:A,B,...; got {item!r}"
        )
    if kind not in _DISTRIBUTIONS:
        raise InvalidArgumentError(
            f"--param {name}: unknown distribution {kind!r}{did_you_mean(kind, _DISTRIBUTIONS)}; "
            f"known: {', '.join(_DISTRIBUTIONS)}"
        )
    parts = [p.strip() for p in args.split(",") if p.strip()]
    if kind == "choice":
        if not parts:
            raise InvalidArgumentError(f"--param {name}: choice needs at least one value")
        values: list[Any] = []
        for p in parts:
            try:
                values.append(json.loads(p))
            except json.JSONDecodeError:
                values.append(p)
        return name, {"kind": "choice", "values": values}
    if len(parts) != 2:
        raise InvalidArgumentError(f"--param {name}: {kind} takes LOW,HIGH; got {args!r}")
    lo = _convert(parts[0], "int" if kind == "int" else "float", f"--param {name} low")
    hi = _convert(parts[1], "int" if kind == "int" else "float", f"--param {name} high")
    if not lo < hi:
        raise InvalidArgumentError(f"--param {name}: LOW must be below HIGH; got {lo}, {hi}")
    if kind == "loguniform" and lo <= 0:
        raise InvalidArgumentError(f"--param {name}: loguniform needs LOW > 0; got {lo}")
    return name, {"kind": kind, "low": lo, "high": hi}


def config_label(config: dict[str, Any]) -> str:
    """The label a configuration is grouped by: ``"alpha=0.1,epsilon=0.2"`` or ``"default"``."""
    if not config:
        return "default"
    return ",".join(f"{k}={_fmt(v)}" for k, v in config.items())


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


@dataclass
class ExperimentSpec:
    """One sweep or tuning run, as plain data (stored in ``sweep.json``, sent to trials).

    Attributes:
        command: ``"sweep"`` (a grid of configurations x seeds) or ``"tune"`` (a search).
        algorithm: The algorithm's name (``"q-learning"``, ``"ppo"``).
        family: ``"tabular"`` or ``"deep"``.
        problem: The problem (a built-in name or a Gymnasium id).
        seeds: The seeds every configuration runs with (seed k as ``--seed k``).
        fixed: Options and config fields set to one value for every trial.
        grid: Swept keys and their values (sweep: every combination runs).
        space: Tuned keys and their distributions (tune).
        trials: Number of configurations the search tries (tune).
        scheduler: Early stopping of the search: ``"asha"``, ``"median"`` or ``"none"``.
        max_failures: Retries of a trial whose worker died (from its last checkpoint).
        metric: The name of the score trials are compared by (always ``"score"``).
        metric_description: What the score is.
        search_seed: Seed of the search (the sampler of ``tune``).
        trial_per_seed: Whether every (configuration, seed) of a sweep is its own trial
            (always for deep algorithms; for tabular ones all seeds of a configuration
            share one trial unless this is set).
    """

    command: Literal["sweep", "tune"]
    algorithm: str
    family: Family
    problem: str
    seeds: list[int]
    fixed: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    space: dict[str, dict[str, Any]] = field(default_factory=dict)
    trials: int = 0
    scheduler: str = "asha"
    max_failures: int = 2
    metric: str = "score"
    metric_description: str = ""
    search_seed: int = 0
    trial_per_seed: bool = False

    def to_json(self) -> dict[str, Any]:
        """The spec as a JSON object."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> ExperimentSpec:
        """The spec stored by :meth:`to_json`.

        Raises:
            InvalidArgumentError: If ``doc`` is not such an object.
        """
        names = {f.name for f in dataclasses.fields(cls)}
        if not isinstance(doc, dict) or not {"command", "algorithm", "problem"} <= set(doc):
            raise InvalidArgumentError("the sweep folder's description is malformed")
        return cls(**{k: v for k, v in doc.items() if k in names})

    def configurations(self) -> list[dict[str, Any]]:
        """Every combination of the grid's values, in order (one empty config if no grid)."""
        keys = list(self.grid)
        return [
            dict(zip(keys, vals, strict=True)) for vals in itertools.product(*self.grid.values())
        ]

    def settings(self, config: dict[str, Any]) -> dict[str, Any]:
        """The fixed options with one configuration's values over them."""
        return {**self.fixed, **config}


def build_spec(
    command: Literal["sweep", "tune"],
    algorithm: str,
    problem: str,
    *,
    seeds: int | list[int],
    options: dict[str, Any] | None = None,
    set_values: dict[str, list[Any]] | None = None,
    space: dict[str, dict[str, Any]] | None = None,
    trials: int = 0,
    scheduler: str = "asha",
    max_failures: int = 2,
    search_seed: int = 0,
    trial_per_seed: bool = False,
) -> ExperimentSpec:
    """A checked :class:`ExperimentSpec`: every option, key and value is validated here.

    Keys of ``set_values`` given one value are fixed for every trial; keys given several
    are swept. For a tabular algorithm the keys are its options (by parameter name,
    ``alpha``, or flag, ``--alpha``); for a deep one, fields of its config class.

    Raises:
        InvalidArgumentError: Unknown algorithm, option, key (with a suggestion), a bad
            value, or a problem the algorithm cannot run on.
    """
    from policylab.experiments.problems import check_problem

    name, family = family_of(algorithm)
    seed_list = (
        list(range(check_count(seeds, "--seeds")))
        if isinstance(seeds, int)
        else [int(check_seed(s, "seed") or 0) for s in seeds]
    )
    if not seed_list:
        raise InvalidArgumentError("--seeds must be at least 1")
    fixed = dict(options or {})
    grid: dict[str, list[Any]] = {}
    keys = _keys(name, family)
    for key, values in (set_values or {}).items():
        param, kind = _key(name, family, keys, key, "--set")
        conv = [_convert(v, kind, f"--set {key}") if kind else v for v in values]
        if len(conv) == 1:
            fixed[param] = conv[0]
        else:
            if len(set(map(json.dumps, conv))) != len(conv):
                raise InvalidArgumentError(f"--set {key} lists a value twice")
            grid[param] = conv
    tuned: dict[str, dict[str, Any]] = {}
    for key, dist in (space or {}).items():
        param, kind = _key(name, family, keys, key, "--param")
        if kind == "flag" and dist["kind"] != "choice":
            raise InvalidArgumentError(f"--param {key} is a switch: use choice:true,false")
        if kind == "int" and dist["kind"] in ("uniform", "loguniform"):
            raise InvalidArgumentError(f"--param {key} is an integer: use int:LOW,HIGH")
        if dist["kind"] == "choice" and kind:
            dist = {**dist, "values": [_convert(v, kind, f"--param {key}") for v in dist["values"]]}
        tuned[param] = dist
    spec = ExperimentSpec(
        command=command,
        algorithm=name,
        family=family,
        problem=problem,
        seeds=seed_list,
        fixed=fixed,
        grid=grid,
        space=tuned,
        trials=trials,
        scheduler=scheduler,
        max_failures=check_count(max_failures, "max_failures", minimum=0),
        search_seed=search_seed,
        trial_per_seed=bool(trial_per_seed) or (family == "deep" and command == "sweep"),
    )
    check_problem(spec)
    return spec


def _keys(name: str, family: Family) -> dict[str, tuple[str, str]]:
    """``{accepted key: (param, kind)}``: what ``--set`` and ``--param`` may name."""
    if family == "deep":
        return {f: (f, "") for f in _deep_fields(name) if f != "seed"}
    out: dict[str, tuple[str, str]] = {}
    for flag, (param, kind) in _tabular_options(name).items():
        out[param] = (param, kind)
        out[flag.lstrip("-")] = (param, kind)
        out[flag] = (param, kind)
    return out


def _key(
    name: str, family: Family, keys: dict[str, tuple[str, str]], key: str, where: str
) -> tuple[str, str]:
    if key in keys:
        return keys[key]
    if family == "deep" and key == "seed":
        raise InvalidArgumentError(f"{where} seed: the seeds are set by --seeds")
    shown = sorted({p for p, _ in keys.values()})
    what = "config field" if family == "deep" else "option"
    raise InvalidArgumentError(
        f"{where} {key!r} is not a {what} of {name}{did_you_mean(key, shown)}; known: "
        f"{', '.join(shown)}"
    )
