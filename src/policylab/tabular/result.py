"""The result of every tabular learner: tables, bookkeeping and the error curve."""

from __future__ import annotations

from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.policy import Policy

__all__ = ["LearnResult"]


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


@dataclass
class LearnResult:
    """What a tabular learner returns (``policylab learn ... --json`` prints it).

    Attributes:
        algorithm: The algorithm's registry name (``"mc-control"``).
        problem: The problem's name.
        states: State labels, index order of ``q`` and ``v``.
        actions: Action labels.
        q: Estimated action values Q (S, A) (0 where a is not in A(s)).
        v: Estimated state values V (S,), or None if the learner has no V.
        policy: The greedy policy of ``q`` (or the learned policy of a control method)
            as (S, A) probabilities; all-zero rows for terminal states.
        terminal: (S,) True for terminal states.
        action_mask: (S, A) A(s).
        counts: (S, A) number of updates of each Q(s, a) (visits that were averaged).
        episodes: Episodes run.
        steps: Environment steps taken, over all episodes.
        seconds: Wall-clock time of the learning (compilation excluded after the first
            run; the kernels are cached on disk).
        episode_returns: (episodes,) the discounted return G_0 of every episode.
        checkpoints: (K,) episode counts at which the error was recorded (the x axis).
        error_max: (K,) max |estimate - exact| at each checkpoint (empty if no truth).
        error_rms: (K,) RMS error at each checkpoint.
        optimal_actions: (K,) share of non-terminal states whose greedy action is best
            under the exact action values (NaN for V-only learners).
        error_target: What the error is measured against (``"q_pi"``, ``"v_pi"``,
            ``"q*"``, ``"v*"``), or None without a known model.
        truncated: Episodes cut by the step limit (not used for Monte Carlo updates).
        episode_lengths: (episodes,) the steps of every episode, or None where the
            learner does not keep them.
        first_actions: (episodes,) the index of A_0 of every episode (one-step TD
            control: Figure 6.5 counts the "left" actions in A), else None.
        params: The settings of the run (for the record and for displays).
        mdp: The FiniteMDP learned on, if any (for :meth:`to_policy` and figures).
    """

    algorithm: str
    problem: str
    states: tuple[Hashable, ...]
    actions: tuple[Hashable, ...]
    q: NDArray[np.float64]
    v: NDArray[np.float64] | None
    policy: NDArray[np.float64]
    terminal: NDArray[np.bool_]
    action_mask: NDArray[np.bool_]
    counts: NDArray[np.float64]
    episodes: int
    steps: int
    seconds: float
    episode_returns: NDArray[np.float64]
    checkpoints: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    error_max: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    error_rms: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    optimal_actions: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    error_target: str | None = None
    truncated: int = 0
    episode_lengths: NDArray[np.int64] | None = None
    first_actions: NDArray[np.int64] | None = None
    params: dict[str, Any] = field(default_factory=dict)
    mdp: FiniteMDP | None = None

    @property
    def error(self) -> dict[str, float | None] | None:
        """The final error ``{"max", "rms", "optimal_actions"}``, or None without truth."""
        if self.error_target is None or len(self.checkpoints) == 0:
            return None
        return {
            "max": _finite_or_none(self.error_max[-1]),
            "rms": _finite_or_none(self.error_rms[-1]),
            "optimal_actions": _finite_or_none(self.optimal_actions[-1]),
        }

    def to_policy(self) -> Policy:
        """The learned policy as a :class:`~policylab.Policy` over the MDP learned on.

        Raises:
            InvalidArgumentError: If the run had no FiniteMDP (general Gymnasium path).
        """
        from policylab.exceptions import InvalidArgumentError
        from policylab.mdp.policy import Policy

        if self.mdp is None:
            raise InvalidArgumentError(
                "this result was learned on a Gymnasium env without a FiniteMDP; use .policy "
                "(the (S, A) array over .states)"
            )
        return Policy.from_array(self.mdp, self.policy)

    def policy_dict(self) -> dict[str, dict[str, float]]:
        """``{str(state): {str(action): probability}}`` over non-terminal states, nonzero only."""
        out: dict[str, dict[str, float]] = {}
        for s in np.flatnonzero(~self.terminal):
            row = self.policy[s]
            out[str(self.states[s])] = {
                str(self.actions[a]): float(row[a]) for a in np.flatnonzero(row)
            }
        return out

    def to_json(self) -> dict[str, Any]:
        """The ``policylab learn --json`` object (the command line's documented JSON output)."""
        return {
            "states": [str(s) for s in self.states],
            "actions": [str(a) for a in self.actions],
            "q": [[float(x) for x in row] for row in self.q],
            "v": None if self.v is None else [float(x) for x in self.v],
            "policy": self.policy_dict(),
            "episodes": int(self.episodes),
            "steps": int(self.steps),
            "seconds": float(self.seconds),
            "episode_returns": [float(x) for x in self.episode_returns],
            "error": self.error,
        }

    def __repr__(self) -> str:
        err = self.error
        tail = (
            ""
            if err is None
            else f", error {self.error_target} max={err['max']:.4g} rms={err['rms']:.4g}"
        )
        return (
            f"LearnResult({self.algorithm} on {self.problem}: {self.episodes} episodes, "
            f"{self.steps} steps, {self.seconds:.3g} s{tail})"
        )
