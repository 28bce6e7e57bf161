"""Policies (notes section 5): deterministic pi: S -> A and stochastic pi(a | s)."""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from policylab.exceptions import InvalidPolicyError, UnknownLabelError
from policylab.validation import check_float_array, check_generator, fmt_number

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

    from policylab.mdp.finite import FiniteMDP

__all__ = ["POLICY_TOL", "Policy"]

#: Tolerance on the sum of a policy row and on mass placed on unavailable actions.
POLICY_TOL = 1e-8


class Policy:
    """A policy pi(a | s) over an MDP's states and actions, as an (S, A) array.

    Rows of non-terminal states sum to 1 and are zero on unavailable actions; rows of
    terminal states are all zero (no action is taken there). A deterministic policy has
    one 1 per non-terminal row. Build one with :meth:`deterministic`, :meth:`stochastic`,
    :meth:`uniform` or :meth:`from_array`.
    """

    __slots__ = ("_probs", "actions", "mask", "states", "terminal")

    def __init__(self, mdp: FiniteMDP, probs: NDArray[np.float64]) -> None:
        _require_mdp(mdp)
        self.states = mdp.states
        self.actions = mdp.actions
        self.terminal = mdp.terminal
        self.mask = mdp.action_mask
        self._probs = _validated(mdp, probs)

    # ---------------------------------------------------------------- constructors
    @classmethod
    def from_array(cls, mdp: FiniteMDP, probs: ArrayLike) -> Policy:
        """A policy from an (S, A) array of probabilities, in the MDP's index order.

        Raises:
            InvalidPolicyError: If the shape is wrong, a non-terminal row does not sum
                to 1, or mass lies on an unavailable action.
        """
        _require_mdp(mdp)
        arr = check_float_array(
            probs,
            "policy array",
            expected=f"an (S, A) = ({mdp.n_states}, {mdp.n_actions}) array of numbers",
            error=InvalidPolicyError,
        )
        return cls(mdp, arr)

    @classmethod
    def deterministic(cls, mdp: FiniteMDP, mapping: Mapping[Hashable, Hashable]) -> Policy:
        """pi: S -> A from ``{state: action}`` labels (every non-terminal state needed).

        Example: ``Policy.deterministic(robot, {"low": "recharge", "high": "search"})``.
        """
        table = {}
        for s, a in _as_mapping(mapping, "deterministic").items():
            try:
                hash(a)
            except TypeError:
                raise InvalidPolicyError(
                    f"a deterministic policy maps each state to one action label; state {s!r} "
                    f"is given {a!r} ({type(a).__name__}); for several actions use "
                    "Policy.stochastic with {state: {action: probability}}"
                ) from None
            table[s] = {a: 1.0}
        return cls.stochastic(mdp, table)

    @classmethod
    def stochastic(
        cls, mdp: FiniteMDP, mapping: Mapping[Hashable, Mapping[Hashable, float]]
    ) -> Policy:
        """pi(a | s) from ``{state: {action: probability}}`` labels.

        Every non-terminal state must be given; actions left out get probability 0.
        """
        _require_mdp(mdp)
        probs = np.zeros((mdp.n_states, mdp.n_actions))
        given = set()
        for s_lab, row in _as_mapping(mapping, "stochastic").items():
            try:
                s = mdp.state_index(s_lab)
            except UnknownLabelError as e:
                raise InvalidPolicyError(f"policy names {e}") from None
            if mdp.terminal[s]:
                continue
            given.add(s)
            for a_lab, pr in _as_mapping(row, f"row of state {s_lab!r}").items():
                try:
                    a = mdp.action_index(a_lab)
                except UnknownLabelError as e:
                    raise InvalidPolicyError(f"policy for state {s_lab!r} names {e}") from None
                probs[s, a] += _number(pr, f"pi({a_lab!r} | {s_lab!r})")
        missing = [mdp.states[s] for s in np.flatnonzero(~mdp.terminal) if s not in given]
        if missing:
            raise InvalidPolicyError(
                f"policy gives no action for non-terminal state(s) {missing[:8]!r}"
                + (f" ({len(missing)} in all)" if len(missing) > 8 else "")
            )
        return cls(mdp, probs)

    @classmethod
    def uniform(cls, mdp: FiniteMDP) -> Policy:
        """The equiprobable random policy over A(s) in every non-terminal state."""
        _require_mdp(mdp)
        m = mdp.action_mask.astype(np.float64)
        n = m.sum(axis=1, keepdims=True)
        return cls(mdp, np.divide(m, n, out=np.zeros_like(m), where=n > 0))

    @classmethod
    def from_actions(cls, mdp: FiniteMDP, actions: ArrayLike) -> Policy:
        """A deterministic policy from one action index per state (ignored on terminals)."""
        _require_mdp(mdp)
        arr = np.asarray(actions)
        if arr.dtype.kind not in "iu" and not (
            arr.dtype.kind == "f" and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr))
        ):
            raise InvalidPolicyError(
                f"from_actions takes one action index (an integer) per state; got an array "
                f"of dtype {arr.dtype}"
            )
        idx = arr.astype(np.int64)
        if idx.shape != (mdp.n_states,):
            raise InvalidPolicyError(
                f"expected {mdp.n_states} action indices; got shape {idx.shape}"
            )
        probs = np.zeros((mdp.n_states, mdp.n_actions))
        live = ~mdp.terminal
        if np.any(live & ((idx < 0) | (idx >= mdp.n_actions))):
            raise InvalidPolicyError(f"action indices must lie in [0, {mdp.n_actions})")
        probs[np.flatnonzero(live), idx[live]] = 1.0
        return cls(mdp, probs)

    @classmethod
    def _valid(cls, mdp: FiniteMDP, probs: NDArray[np.float64]) -> Policy:
        """A policy from an (S, A) float64 array already known to be one (no checks, no copy).

        For the solvers' own greedy rows: every non-terminal row a distribution on
        A(s), every terminal row zero. The array becomes read-only and is kept.
        """
        pol = cls.__new__(cls)
        pol.states = mdp.states
        pol.actions = mdp.actions
        pol.terminal = mdp.terminal
        pol.mask = mdp.action_mask
        probs.flags.writeable = False
        pol._probs = probs
        return pol

    # ---------------------------------------------------------------- views
    @property
    def probs(self) -> NDArray[np.float64]:
        """The (S, A) array pi(a | s) (read-only)."""
        return self._probs

    @property
    def is_deterministic(self) -> bool:
        """Whether every non-terminal row puts all its mass on one action."""
        live = ~self.terminal
        return bool(np.all(np.isclose(self._probs[live].max(axis=1), 1.0)))

    def check_fits(self, mdp: FiniteMDP, where: str = "policy") -> Policy:
        """This policy, if it was built for ``mdp`` (same states, actions, A(s)).

        Raises:
            InvalidPolicyError: Naming both sizes and the first labels of each, so that a
                policy of one problem passed with another is caught, not mis-indexed.
        """
        if self.states != mdp.states or self.actions != mdp.actions:
            raise InvalidPolicyError(
                f"{where} was built for another MDP ({len(self.states)} states, actions "
                f"{list(self.actions)[:8]!r}); MDP {mdp.name!r} has {mdp.n_states} states and "
                f"actions {list(mdp.actions)[:8]!r}"
            )
        if not np.array_equal(self.mask, mdp.action_mask):
            raise InvalidPolicyError(
                f"{where} was built for an MDP with other available actions A(s) than "
                f"MDP {mdp.name!r}"
            )
        return self

    def action_indices(self) -> NDArray[np.int64]:
        """The most probable action index of each state (-1 for terminal states)."""
        out: NDArray[np.int64] = self._probs.argmax(axis=1).astype(np.int64)
        out[self.terminal] = -1
        return out

    def __call__(self, state: Hashable) -> Hashable:
        """pi(s) for a deterministic policy: the action label chosen in a state."""
        if not self.is_deterministic:
            raise InvalidPolicyError("calling a stochastic policy; use prob() or sample()")
        s = self.states.index(state) if state in self.states else None
        if s is None:
            raise UnknownLabelError(f"unknown state {state!r}")
        return self.actions[int(self._probs[s].argmax())]

    def prob(self, action: Hashable, state: Hashable) -> float:
        """pi(a | s) by labels."""
        if state not in self.states or action not in self.actions:
            raise UnknownLabelError(f"unknown state {state!r} or action {action!r}")
        return float(self._probs[self.states.index(state), self.actions.index(action)])

    def sample(self, s: int, rng: np.random.Generator) -> int:
        """Draw an action index in state index ``s``."""
        if not 0 <= s < len(self.states) or self.terminal[s]:
            raise InvalidPolicyError(
                f"sample takes the index of a non-terminal state in [0, {len(self.states)}); "
                f"got {s!r}"
            )
        check_generator(rng, error=InvalidPolicyError)
        row = self._probs[s]
        k = int(np.searchsorted(np.cumsum(row), rng.random(), side="right"))
        return min(k, int(np.flatnonzero(row)[-1]))

    def to_dict(self) -> dict[str, dict[str, float]]:
        """``{str(state): {str(action): probability}}`` of non-terminal states, nonzero only."""
        out: dict[str, dict[str, float]] = {}
        for s in np.flatnonzero(~self.terminal):
            out[str(self.states[s])] = {
                str(self.actions[a]): float(self._probs[s, a])
                for a in np.flatnonzero(self._probs[s])
            }
        return out

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Policy):
            return NotImplemented
        return (
            self.states == other.states
            and self.actions == other.actions
            and np.allclose(self._probs, other._probs, atol=POLICY_TOL)
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        kind = "deterministic" if self.is_deterministic else "stochastic"
        return f"Policy({kind}, states={len(self.states)}, actions={len(self.actions)})"


def _require_mdp(mdp: Any) -> None:
    from policylab.mdp.finite import FiniteMDP
    from policylab.mdp.postdecision import PostDecisionMDP

    if not isinstance(mdp, FiniteMDP | PostDecisionMDP):
        raise InvalidPolicyError(
            f"a policy is built for a FiniteMDP or a PostDecisionMDP; got "
            f"{type(mdp).__name__} {mdp!r:.60}"
        )


def _as_mapping(x: Any, what: str) -> Mapping[Any, Any]:
    if not isinstance(x, Mapping):
        raise InvalidPolicyError(
            f"{what} policy must be given as a mapping; got {type(x).__name__}"
        )
    return x


def _number(x: Any, what: str) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        raise InvalidPolicyError(f"{what} must be a number; got {x!r}") from None


def _validated(mdp: FiniteMDP, probs: NDArray[np.float64]) -> NDArray[np.float64]:
    S, A = mdp.n_states, mdp.n_actions
    if probs.shape != (S, A):
        raise InvalidPolicyError(
            f"policy array has shape {probs.shape}; expected (S, A) = ({S}, {A})"
        )
    p = np.array(probs, dtype=np.float64)
    p[mdp.terminal] = 0.0
    live = ~mdp.terminal
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        s, a = map(int, np.argwhere(~np.isfinite(p) | (p < 0))[0])
        raise InvalidPolicyError(
            f"pi({mdp.actions[a]!r} | {mdp.states[s]!r}) = {fmt_number(p[s, a])}; "
            "probabilities must be finite and >= 0"
        )
    off = live[:, None] & ~mdp.action_mask & (p > POLICY_TOL)
    if np.any(off):
        s, a = map(int, np.argwhere(off)[0])
        raise InvalidPolicyError(
            f"policy puts probability {fmt_number(p[s, a])} on action {mdp.actions[a]!r} in state "
            f"{mdp.states[s]!r}, where it is not available; A({mdp.states[s]!r}) = "
            f"{mdp.available_actions(mdp.states[s])!r}"
        )
    p[~mdp.action_mask] = 0.0
    sums = p.sum(axis=1)
    bad = live & (np.abs(sums - 1.0) > POLICY_TOL * max(1, A))
    if np.any(bad):
        s = int(np.flatnonzero(bad)[0])
        raise InvalidPolicyError(
            f"pi(. | {mdp.states[s]!r}) sums to {fmt_number(sums[s], near=1.0)}; each "
            "non-terminal row must sum to 1"
        )
    np.divide(p, sums[:, None], out=p, where=live[:, None])  # in place: no (S, A) copy
    p.flags.writeable = False
    return p
