"""The problem a trial runs on, built the way ``policylab learn`` and ``train`` build it.

A tabular trial runs on a FiniteMDP (a built-in problem, or a Gymnasium id whose env
exposes its model ``P``), so that all seeds of a configuration run at once in compiled
code and every learned table is scored against the exact answer of the planning layer.
A deep trial runs on a Gymnasium id.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from policylab.exceptions import InvalidArgumentError, UnknownProblemError

if TYPE_CHECKING:
    from policylab.experiments.spec import ExperimentSpec
    from policylab.mdp.finite import FiniteMDP
    from policylab.tabular.truth import GroundTruth

__all__ = [
    "check_problem",
    "finite_problem",
    "ground_truth",
    "named_policy",
    "reachable_states",
]

_GYM_HINT = ", or a Gymnasium id with a model `P` (FrozenLake-v1, CliffWalking-v1, Taxi-v4)"


def finite_problem(name: str, gamma: float | None = None) -> FiniteMDP:
    """The FiniteMDP of a problem name, as ``policylab learn NAME`` learns on it.

    Raises:
        UnknownProblemError: A name that is neither a built-in problem nor a Gymnasium
            id with a model ``P``.
    """
    from policylab.mdp.finite import FiniteMDP
    from policylab.problems.registry import find_problem, unknown_problem_message

    spec = find_problem(name)
    if spec is not None:
        mdp = spec.builder()
    else:
        if "-v" not in name:
            raise UnknownProblemError(unknown_problem_message(name, _GYM_HINT))
        import gymnasium as gym

        try:
            env = gym.make(name)
        except Exception as e:  # gymnasium raises its own error types for unknown ids
            raise UnknownProblemError(
                unknown_problem_message(name, _GYM_HINT)
                + f" (Gymnasium: {' '.join(str(e).split())})"
            ) from None
        if getattr(env.unwrapped, "P", None) is None:
            raise UnknownProblemError(
                f"{name} has no model P; a tabular sweep runs on a finite MDP (a built-in "
                f"problem{_GYM_HINT})"
            )
        return FiniteMDP.from_gymnasium(env, gamma=1.0 if gamma is None else gamma, name=name)
    return mdp if gamma is None else mdp.with_gamma(gamma)


def named_policy(problem: str, mdp: FiniteMDP, policy: str | None) -> Any:
    """The policy a prediction learner evaluates: ``uniform`` (default) or a named one.

    Raises:
        InvalidArgumentError: A name the problem does not register.
    """
    from policylab.mdp.policy import Policy
    from policylab.problems.registry import find_problem
    from policylab.validation import did_you_mean

    if policy is None or policy == "uniform":
        return Policy.uniform(mdp)
    spec = find_problem(problem)
    names = sorted(spec.policies) if spec else []
    if spec is None or policy not in spec.policies:
        raise InvalidArgumentError(
            f"unknown policy {policy!r} for {problem!r}{did_you_mean(policy, ['uniform', *names])}"
            f"; known: {', '.join(['uniform', *names])}"
        )
    return spec.policies[policy](mdp)


def ground_truth(algorithm: str, mdp: FiniteMDP, policy: Any) -> GroundTruth:
    """The exact answer a tabular learner is scored against: q* (control) or v_pi / q_pi."""
    from policylab.tabular.registry import algorithm as get_algorithm
    from policylab.tabular.truth import GroundTruth

    if get_algorithm(algorithm).kind == "control":
        return GroundTruth.control(mdp)
    return GroundTruth.prediction(mdp, policy, on="v")


def reachable_states(mdp: FiniteMDP) -> Any:
    """(S,) mask of the states reachable from the start distribution under some policy.

    States no episode can visit (CliffWalking's cliff cells, say) keep a learner's
    initial values forever; scoring a learner on them would only add a constant.
    """
    import numpy as np
    import scipy.sparse as sp
    from scipy.sparse.csgraph import breadth_first_order

    S, A = mdp.n_states, mdp.n_actions
    pick = sp.csr_array(
        (np.ones(S * A), (np.repeat(np.arange(S), A), np.arange(S * A))), shape=(S, S * A)
    )
    graph = (pick @ mdp.transition_matrix).tocsr()
    seen = np.zeros(S, dtype=bool)
    for s in np.flatnonzero(np.asarray(mdp.initial) > 0):
        if not seen[s]:
            seen[breadth_first_order(graph, int(s), directed=True, return_predecessors=False)] = (
                True
            )
    return seen


def check_problem(spec: ExperimentSpec) -> None:
    """Refuse, before any trial, a problem the experiment's algorithm cannot run on.

    Raises:
        UnknownProblemError: An unknown problem or Gymnasium id.
        InvalidArgumentError: A bad option value (checked by building one configuration).
    """
    if spec.family == "tabular":
        from policylab.experiments.trials import tabular_kwargs
        from policylab.tabular.registry import algorithm

        learner = algorithm(spec.algorithm).learner
        for config in _corners(spec):  # one episode of each: the learner checks its values
            mdp, kwargs = tabular_kwargs(spec, config)
            learner(mdp, **{**kwargs, "seed": 0, "episodes": 1, "progress": False})
        return
    from policylab.deep.common.config import config_from_dict
    from policylab.deep.common.envs import check_env_id
    from policylab.deep.zoo import ALGORITHMS

    try:
        check_env_id(spec.problem)
    except InvalidArgumentError as e:
        raise UnknownProblemError(str(e)) from None
    cls = ALGORITHMS[spec.algorithm].config_class
    for config in _corners(spec):
        fields = deep_fields(spec, config)
        fields.pop("steps", None)
        config_from_dict(cls, fields)


def _corners(spec: ExperimentSpec) -> list[dict[str, Any]]:
    """Configurations to check before running: every grid point, or each search bound."""
    if spec.command == "sweep":
        return spec.configurations()
    ends: list[dict[str, Any]] = []
    for side in (0, 1):
        config = {}
        for k, d in spec.space.items():
            config[k] = d["values"][-side] if d["kind"] == "choice" else (d["low"], d["high"])[side]
        ends.append(config)
    for k, d in spec.space.items():  # every choice once
        if d["kind"] == "choice":
            ends.extend({**ends[0], k: v} for v in d["values"])
    return ends


def deep_fields(spec: ExperimentSpec, config: dict[str, Any], seed: int = 0) -> dict[str, Any]:
    """A deep trial's config fields: the tuned defaults, then the fixed fields and ``config``."""
    from policylab.deep.zoo import default_config

    fields, tuned_steps = default_config(spec.algorithm, spec.problem)
    fields.update(spec.settings(config))
    fields["seed"] = seed
    fields.setdefault("steps", tuned_steps or 100_000)
    return fields
