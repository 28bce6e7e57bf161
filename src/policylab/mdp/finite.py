"""The finite MDP of the notes (section 4.3): states, actions, one-step dynamics, gamma.

A :class:`FiniteMDP` stores the one-step dynamics p(s', r | s, a) as a sparse outcome
table: for each pair (s, a), in row ``s * A + a``, a run of outcomes
``(probability, next state, reward)``. Reward *distributions* are kept; the expected
reward r(s, a) and the transition matrices are derived from the table on first use.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from policylab.exceptions import (
    InvalidMDPError,
    ShapeError,
    UnknownLabelError,
)
from policylab.mdp.grid import GridLayout
from policylab.validation import check_float_array, check_gamma, check_generator, fmt_number

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["PROB_TOL", "FiniteMDP", "Outcome"]

#: Tolerance on the sum of the probabilities of one (state, action) pair.
PROB_TOL = 1e-8

Outcome = tuple[float, Hashable, float]
"""One outcome of p(s', r | s, a): (probability, next state label, reward)."""


def _fmt(label: Hashable) -> str:
    return repr(label)


def _sum_error(state: Hashable, action: Hashable, total: float, tol: float) -> InvalidMDPError:
    """The error of a pair whose probabilities do not sum to 1, with the deviation shown."""
    return InvalidMDPError(
        f"p(. | s={_fmt(state)}, a={_fmt(action)}) sums to {fmt_number(total, near=1.0)} (off by "
        f"{float(total) - 1.0:+.3g}); each (state, action) must sum to 1 (tolerance {tol:.3g})"
    )


def _fmt_items(x: Any) -> str:
    """A tuple or list as in a message: its numbers by ``fmt_number`` (no ``np.float64(...)``)."""
    if isinstance(x, tuple | list):
        inner = ", ".join(
            fmt_number(v) if isinstance(v, int | float | np.number) else repr(v) for v in x
        )
        return f"({inner}{',' if len(x) == 1 else ''})" if isinstance(x, tuple) else f"[{inner}]"
    return fmt_number(x) if isinstance(x, int | float | np.number) else repr(x)


def _index_of(labels: Sequence[Hashable]) -> dict[Hashable, int]:
    index: dict[Hashable, int] = {}
    for i, lab in enumerate(labels):
        try:
            if lab in index:
                raise InvalidMDPError(f"label {lab!r} appears twice; labels must be unique")
        except TypeError:
            raise InvalidMDPError(f"label {lab!r} is not hashable") from None
        index[lab] = i
    return index


@dataclass(frozen=True, eq=False)
class FiniteMDP:
    """A finite Markov decision process with a sparse outcome table.

    Build one with :meth:`from_dynamics`, :meth:`from_arrays` or :meth:`from_gymnasium`
    rather than calling the constructor; the constructor validates its arrays all the
    same.

    Attributes:
        states: State labels, S+ (terminal states included), in index order.
        actions: Action labels, in index order.
        gamma: Discount rate in [0, 1].
        terminal: Boolean mask (S,): True for terminal states (value 0, no dynamics).
        action_mask: Boolean mask (S, A): True where action a is in A(s). Rows of
            terminal states are all False.
        indptr: (S * A + 1,) offsets: the outcomes of (s, a) are
            ``indptr[s * A + a] : indptr[s * A + a + 1]``.
        next_states: (K,) next-state index of each outcome.
        probs: (K,) probability of each outcome.
        rewards: (K,) reward of each outcome.
        initial: (S,) start-state distribution (zero on terminal states).
        name: A short name for messages and displays.
        grid: How states map to grid cells, for grid-shaped problems; else None.
        meta: Problem-specific facts for displays and figures (for example ``"x"``,
            the abscissa of each state of a one-dimensional problem). Never read by
            solvers or learners.
    """

    states: tuple[Hashable, ...]
    actions: tuple[Hashable, ...]
    gamma: float
    terminal: NDArray[np.bool_]
    action_mask: NDArray[np.bool_]
    indptr: NDArray[np.int64]
    next_states: NDArray[np.integer[Any]]
    probs: NDArray[np.float64]
    rewards: NDArray[np.float64]
    initial: NDArray[np.float64]
    name: str = "mdp"
    grid: GridLayout | None = field(default=None)
    meta: Mapping[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ validation
    def __post_init__(self) -> None:
        S, A = len(self.states), len(self.actions)
        object.__setattr__(self, "gamma", check_gamma(self.gamma))
        if S == 0 or A == 0:
            raise InvalidMDPError(
                f"an MDP needs at least one state and one action; got {S} and {A}"
            )
        _index_of(self.states)
        _index_of(self.actions)
        term = np.asarray(self.terminal, dtype=bool)
        mask = np.asarray(self.action_mask, dtype=bool)
        if term.shape != (S,):
            raise ShapeError(f"terminal mask must have shape ({S},); got {term.shape}")
        if mask.shape != (S, A):
            raise ShapeError(f"action_mask must have shape ({S}, {A}); got {mask.shape}")
        indptr = np.asarray(self.indptr, dtype=np.int64)
        if indptr.shape != (S * A + 1,) or indptr[0] != 0 or np.any(np.diff(indptr) < 0):
            raise ShapeError(f"indptr must be non-decreasing with shape ({S * A + 1},), from 0")
        K = int(indptr[-1])
        nxt = np.asarray(self.next_states, dtype=np.int32 if S < 2**31 else np.int64)
        probs = np.asarray(self.probs, dtype=np.float64)
        rewards = np.asarray(self.rewards, dtype=np.float64)
        for arr, what in ((nxt, "next_states"), (probs, "probs"), (rewards, "rewards")):
            if arr.shape != (K,):
                raise ShapeError(f"{what} must have shape ({K},) to match indptr; got {arr.shape}")
        if K and (nxt.min() < 0 or nxt.max() >= S):
            raise InvalidMDPError(
                f"next-state indices must lie in [0, {S}); got {nxt.min()}..{nxt.max()}"
            )
        mask = mask & ~term[:, None]
        counts = np.diff(indptr).reshape(S, A)
        object.__setattr__(self, "terminal", term)
        object.__setattr__(self, "action_mask", mask)
        object.__setattr__(self, "indptr", indptr)
        object.__setattr__(self, "next_states", nxt)
        object.__setattr__(self, "probs", probs)
        object.__setattr__(self, "rewards", rewards)
        self._check_probabilities(counts)
        init = np.asarray(self.initial, dtype=np.float64)
        if init.shape != (S,):
            raise ShapeError(f"initial distribution must have shape ({S},); got {init.shape}")
        if not np.all(np.isfinite(init)) or np.any(init < 0):
            raise InvalidMDPError("initial distribution has negative or non-finite entries")
        if np.any(init[term] > 0):
            bad = self.states[int(np.flatnonzero(init * term)[0])]
            raise InvalidMDPError(f"initial distribution puts mass on terminal state {bad!r}")
        if abs(init.sum() - 1.0) > PROB_TOL * max(1.0, S**0.5):
            raise InvalidMDPError(
                f"initial distribution sums to {fmt_number(init.sum(), near=1.0)}; it must sum to 1"
            )
        object.__setattr__(self, "initial", init / init.sum())
        for arr in (
            self.terminal,
            self.action_mask,
            self.indptr,
            self.next_states,
            self.probs,
            self.rewards,
            self.initial,
        ):
            arr.flags.writeable = False

    def _check_probabilities(self, counts: NDArray[np.int64]) -> None:
        A = self.n_actions
        term, mask = self.terminal, self.action_mask
        probs, rewards = self.probs, self.rewards
        if not np.all(np.isfinite(probs)) or np.any(probs < 0):
            k = int(np.flatnonzero(~np.isfinite(probs) | (probs < 0))[0])
            s, a = divmod(int(np.searchsorted(self.indptr, k, side="right") - 1), A)
            raise InvalidMDPError(
                f"p(. | s={_fmt(self.states[s])}, a={_fmt(self.actions[a])}) has probability "
                f"{fmt_number(probs[k])}; probabilities must be finite and >= 0"
            )
        if not np.all(np.isfinite(rewards)):
            k = int(np.flatnonzero(~np.isfinite(rewards))[0])
            s, a = divmod(int(np.searchsorted(self.indptr, k, side="right") - 1), A)
            raise InvalidMDPError(
                f"reward {fmt_number(rewards[k])} in p(. | s={_fmt(self.states[s])}, "
                f"a={_fmt(self.actions[a])}) is not finite"
            )
        bad_term = term & (counts.sum(axis=1) > 0)
        if np.any(bad_term):
            s = int(np.flatnonzero(bad_term)[0])
            raise InvalidMDPError(
                f"terminal state {_fmt(self.states[s])} has outgoing dynamics; terminal "
                "states have value 0 and no actions"
            )
        unavailable = ~mask & ~term[:, None] & (counts > 0)
        if np.any(unavailable):
            s, a = map(int, np.argwhere(unavailable)[0])
            raise InvalidMDPError(
                f"action {_fmt(self.actions[a])} is not in A({_fmt(self.states[s])}) but has "
                "dynamics; mark it available or give it no outcomes"
            )
        no_action = ~term & ~mask.any(axis=1)
        if np.any(no_action):
            s = int(np.flatnonzero(no_action)[0])
            raise InvalidMDPError(
                f"non-terminal state {_fmt(self.states[s])} has no available action; give it "
                "an action or mark it terminal"
            )
        sums = _segment_sum(probs, self.indptr)
        bad = mask.ravel() & (np.abs(sums - 1.0) > PROB_TOL)
        if np.any(bad):
            s, a = divmod(int(np.flatnonzero(bad)[0]), A)
            raise _sum_error(self.states[s], self.actions[a], sums[s * A + a], PROB_TOL)

    # ------------------------------------------------------------------ sizes, labels
    @property
    def n_states(self) -> int:
        """Number of states in S+ (terminal states included)."""
        return len(self.states)

    @property
    def n_actions(self) -> int:
        """Number of actions."""
        return len(self.actions)

    @property
    def n_outcomes(self) -> int:
        """Number of stored outcomes (nonzeros of the outcome table)."""
        return int(self.indptr[-1])

    @property
    def nonterminal(self) -> NDArray[np.bool_]:
        """Boolean mask (S,) of the states of S (non-terminal)."""
        return ~self.terminal

    @cached_property
    def _state_index(self) -> dict[Hashable, int]:
        return _index_of(self.states)

    @cached_property
    def _action_index(self) -> dict[Hashable, int]:
        return _index_of(self.actions)

    def state_index(self, label: Hashable) -> int:
        """Index of a state label.

        Raises:
            UnknownLabelError: If the MDP has no such state.
        """
        try:
            return self._state_index[label]
        except (KeyError, TypeError):
            raise UnknownLabelError(
                f"unknown state {label!r} in MDP {self.name!r}; states are {_short(self.states)}"
            ) from None

    def action_index(self, label: Hashable) -> int:
        """Index of an action label.

        Raises:
            UnknownLabelError: If the MDP has no such action.
        """
        try:
            return self._action_index[label]
        except (KeyError, TypeError):
            raise UnknownLabelError(
                f"unknown action {label!r} in MDP {self.name!r}; actions are {_short(self.actions)}"
            ) from None

    def available_actions(self, state: Hashable) -> list[Hashable]:
        """A(s): the labels of the actions available in a state (empty if terminal)."""
        s = self.state_index(state)
        return [self.actions[a] for a in np.flatnonzero(self.action_mask[s])]

    def outcomes(self, state: Hashable, action: Hashable) -> list[Outcome]:
        """The outcomes (probability, next state label, reward) of p(s', r | s, a)."""
        s, a = self.state_index(state), self.action_index(action)
        lo, hi = self.indptr[s * self.n_actions + a], self.indptr[s * self.n_actions + a + 1]
        return [
            (float(self.probs[k]), self.states[int(self.next_states[k])], float(self.rewards[k]))
            for k in range(lo, hi)
        ]

    def p(self, next_state: Hashable, reward: float, state: Hashable, action: Hashable) -> float:
        """One-step dynamics: probability of next state s' and reward r after (s, a), by labels.

        This is the notes' p(s', r | s, a) of section 4.3.1.
        """
        sp_ = self.state_index(next_state)
        return float(
            sum(
                pr
                for pr, nxt, r in self.outcomes(state, action)
                if self._state_index[nxt] == sp_ and r == reward
            )
        )

    # ------------------------------------------------------------------ derived views
    def _sum_per_pair(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """Sum ``values`` (one per outcome) over the outcomes of each (s, a) pair, in one pass."""
        return _segment_sum(values, self.indptr)

    @cached_property
    def expected_reward(self) -> NDArray[np.float64]:
        """r(s, a) = sum_{s', r} p(s', r | s, a) r, as an (S, A) array (0 where unavailable)."""
        r = self._sum_per_pair(self.probs * self.rewards).reshape(self.n_states, self.n_actions)
        r.flags.writeable = False
        return r

    @cached_property
    def transition_matrix(self) -> sp.csr_array:
        """p(s' | s, a) as one sparse (S * A, S) matrix, row ``s * A + a``.

        Duplicate next states (several rewards for one s') are summed. Rows of
        unavailable actions and of terminal states are empty.
        """
        SA = self.n_states * self.n_actions
        # matching index dtypes let scipy use the model's arrays without copying them
        small = self.n_outcomes < 2**31 and self.next_states.dtype == np.int32
        indptr = self.indptr.astype(np.int32) if small else self.indptr
        m = sp.csr_array(
            (self.probs, self.next_states, indptr), shape=(SA, self.n_states), copy=False
        )
        if not m.has_canonical_format:
            m = m.copy()
            m.sum_duplicates()
        return m

    def transitions(self, action: Hashable) -> sp.csr_array:
        """P_a, the sparse S x S matrix p(s' | s, a) of one action (pymdptoolbox's ``P[a]``)."""
        a = self.action_index(action)
        return sp.csr_array(self.transition_matrix[a :: self.n_actions])

    # ------------------------------------------------------------------ simulation
    def step(self, s: int, a: int, rng: np.random.Generator) -> tuple[int, float, bool]:
        """Sample one step of the dynamics from state index ``s`` with action index ``a``.

        Args:
            s: Index of a non-terminal state.
            a: Index of an action in A(s).
            rng: The random generator to draw from.

        Returns:
            ``(next_state_index, reward, terminated)``.
        """
        from policylab.exceptions import InvalidActionError

        if not (0 <= s < self.n_states and 0 <= a < self.n_actions):
            raise InvalidActionError(
                f"step takes a state index in [0, {self.n_states}) and an action index in "
                f"[0, {self.n_actions}); got s={s!r}, a={a!r} (labels: state_index, action_index)"
            )
        check_generator(rng)
        row = s * self.n_actions + a
        lo, hi = int(self.indptr[row]), int(self.indptr[row + 1])
        if hi == lo:
            if self.terminal[s]:
                raise InvalidActionError(
                    f"state {self.states[s]!r} is terminal; no action can be taken"
                )
            raise InvalidActionError(
                f"action {self.actions[a]!r} is not available in state {self.states[s]!r}; "
                f"A(s) = {self.available_actions(self.states[s])}"
            )
        u = rng.random()
        k = lo + int(np.searchsorted(np.cumsum(self.probs[lo:hi]), u, side="right"))
        k = min(k, hi - 1)
        nxt = int(self.next_states[k])
        return nxt, float(self.rewards[k]), bool(self.terminal[nxt])

    def sample_initial(self, rng: np.random.Generator) -> int:
        """Sample a start state index from the initial distribution."""
        return int(rng.choice(self.n_states, p=self.initial))

    # ------------------------------------------------------------------ variants
    def with_gamma(self, gamma: float) -> FiniteMDP:
        """The same MDP with another discount rate."""
        from dataclasses import replace

        return replace(self, gamma=check_gamma(gamma))

    def __repr__(self) -> str:
        return (
            f"FiniteMDP({self.name!r}, states={self.n_states} "
            f"({int(self.terminal.sum())} terminal), actions={self.n_actions}, "
            f"outcomes={self.n_outcomes}, gamma={self.gamma:g})"
        )

    @property
    def nbytes(self) -> int:
        """Bytes held by the outcome table and masks (the model's own size)."""
        return int(
            sum(
                a.nbytes
                for a in (
                    self.indptr,
                    self.next_states,
                    self.probs,
                    self.rewards,
                    self.terminal,
                    self.action_mask,
                    self.initial,
                )
            )
        )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dynamics(
        cls,
        dynamics: Mapping[Hashable, Mapping[Hashable, Iterable[Sequence[Any]]]],
        gamma: float = 1.0,
        terminal: Iterable[Hashable] = (),
        *,
        actions: Sequence[Hashable] | None = None,
        initial: Hashable | Mapping[Hashable, float] | None = None,
        name: str = "mdp",
        grid: GridLayout | None = None,
        meta: Mapping[str, Any] | None = None,
    ) -> FiniteMDP:
        """Build an MDP from p(s', r | s, a) written as outcome lists, by label.

        Example (the notes' recycling robot, in part)::

            FiniteMDP.from_dynamics(
                {"high": {"search": [(0.7, "high", 4.0), (0.3, "low", 4.0)],
                          "wait": [(1.0, "high", 1.0)]},
                 "low": {...}},
                gamma=0.9)

        Args:
            dynamics: ``{state: {action: [(probability, next_state, reward), ...]}}``.
                The actions listed for a state are A(s). Several outcomes may share a
                next state with different rewards; identical (s', r) outcomes are summed.
            gamma: Discount rate in [0, 1].
            terminal: Terminal state labels (S+ minus S). They may appear as keys with an
                empty mapping, or only as next states.
            actions: Action labels in index order; default: order of first appearance.
            initial: Start state label, or ``{state: probability}``; default: uniform
                over the non-terminal states.
            name: A short name for messages.
            grid: Grid layout for grid-shaped problems.
            meta: Problem-specific facts for displays (see the class docstring).

        Raises:
            InvalidMDPError: On any malformed entry, naming the state and action.
        """
        if not isinstance(dynamics, Mapping):
            raise InvalidMDPError(
                f"dynamics must be a mapping {{state: {{action: [(p, next_state, reward)]}}}}; "
                f"got {type(dynamics).__name__}"
            )
        term_labels = list(terminal)
        states: list[Hashable] = list(dynamics.keys())
        for t in term_labels:
            if t not in dynamics:
                states.append(t)
        s_index = _index_of(states)
        for t in term_labels:
            if dynamics.get(t):
                raise InvalidMDPError(
                    f"terminal state {t!r} is given outgoing dynamics; terminal states have "
                    "value 0 and no actions"
                )
        if actions is None:
            act_list: list[Hashable] = []
            seen: set[Hashable] = set()
            for s, acts in dynamics.items():
                if not isinstance(acts, Mapping):
                    raise InvalidMDPError(
                        f"dynamics[{s!r}] must map actions to outcome lists; "
                        f"got {type(acts).__name__}"
                    )
                for a in acts:
                    if a not in seen:
                        seen.add(a)
                        act_list.append(a)
        else:
            act_list = list(actions)
        a_index = _index_of(act_list)
        S, A = len(states), len(act_list)
        term = np.zeros(S, dtype=bool)
        term[[s_index[t] for t in term_labels]] = True
        mask = np.zeros((S, A), dtype=bool)
        rows: dict[int, dict[tuple[int, float], float]] = {}
        for s_lab, acts in dynamics.items():
            s = s_index[s_lab]
            if not isinstance(acts, Mapping):
                raise InvalidMDPError(
                    f"dynamics[{s_lab!r}] must map actions to outcome lists; "
                    f"got {type(acts).__name__}"
                )
            for a_lab, outs in acts.items():
                if a_lab not in a_index:
                    raise UnknownLabelError(
                        f"action {a_lab!r} in state {s_lab!r} is not in actions {_short(act_list)}"
                    )
                a = a_index[a_lab]
                mask[s, a] = True
                acc: dict[tuple[int, float], float] = {}
                try:
                    outs_list = list(outs)
                except TypeError:
                    raise InvalidMDPError(
                        f"p(. | s={s_lab!r}, a={a_lab!r}) must be a list of (p, next_state, "
                        f"reward); got {outs!r}"
                    ) from None
                for out in outs_list:
                    if not isinstance(out, Sequence) or isinstance(out, str) or len(out) != 3:
                        raise InvalidMDPError(
                            f"outcome {_fmt_items(out)} of p(. | s={s_lab!r}, a={a_lab!r}) must "
                            "be a triple (probability, next_state, reward)"
                        )
                    pr, nxt_lab, r = out
                    try:
                        nxt = s_index[nxt_lab]
                    except (KeyError, TypeError):
                        raise UnknownLabelError(
                            f"p(. | s={s_lab!r}, a={a_lab!r}) names next state {nxt_lab!r}, which "
                            f"is neither a key of dynamics nor in terminal; states are "
                            f"{_short(states)}"
                        ) from None
                    try:
                        pr_f, r_f = float(pr), float(r)
                    except (TypeError, ValueError):
                        raise InvalidMDPError(
                            f"outcome {_fmt_items(out)} of p(. | s={s_lab!r}, a={a_lab!r}): "
                            "probability and reward must be numbers"
                        ) from None
                    key = (nxt, r_f)
                    acc[key] = acc.get(key, 0.0) + pr_f
                rows[s * A + a] = acc
        counts = np.zeros(S * A, dtype=np.int64)
        for row, acc in rows.items():
            counts[row] = len(acc)
        indptr = np.concatenate([[0], np.cumsum(counts)])
        K = int(indptr[-1])
        nxt_arr = np.empty(K, dtype=np.int32)
        p_arr = np.empty(K)
        r_arr = np.empty(K)
        for row, acc in rows.items():
            lo = indptr[row]
            for j, ((nxt, r_f), pr_f) in enumerate(sorted(acc.items())):
                nxt_arr[lo + j], r_arr[lo + j], p_arr[lo + j] = nxt, r_f, pr_f
        init = _initial_from(initial, states, s_index, term)
        return cls(
            states=tuple(states),
            actions=tuple(act_list),
            gamma=gamma,
            terminal=term,
            action_mask=mask,
            indptr=indptr,
            next_states=nxt_arr,
            probs=p_arr,
            rewards=r_arr,
            initial=init,
            name=name,
            grid=grid,
            meta=dict(meta or {}),
        )

    @classmethod
    def from_arrays(
        cls,
        P: ArrayLike | Sequence[Any],
        R: ArrayLike | Sequence[Any],
        gamma: float = 1.0,
        terminal: ArrayLike | Iterable[int] | None = None,
        *,
        action_mask: ArrayLike | None = None,
        initial: ArrayLike | None = None,
        name: str = "mdp",
        states: Sequence[Hashable] | None = None,
        actions: Sequence[Hashable] | None = None,
        meta: Mapping[str, Any] | None = None,
    ) -> FiniteMDP:
        """Build an MDP from transition and reward arrays (pymdptoolbox's convention).

        Args:
            P: Transition probabilities p(s' | s, a): a dense (A, S, S) array, or a list
                of A sparse (or dense) S x S matrices.
            R: Rewards: an (S, A) array r(s, a), an (A, S, S) array r(s, a, s') (dense),
                or a list of A S x S matrices r(s, a, s') (sparse ones give the rewards
                at the stored entries of P).
            gamma: Discount rate in [0, 1].
            terminal: Terminal states, as a boolean mask (S,) or a list of indices. Their
                rows of P and R are ignored.
            action_mask: Optional boolean (S, A) mask of available actions; default all.
            initial: Optional start distribution (S,); default uniform over S.
            name: A short name for messages.
            states: Optional state labels (default 0..S-1).
            actions: Optional action labels (default 0..A-1).
            meta: Problem-specific facts for displays (see the class docstring).

        Raises:
            ShapeError: If the shapes do not fit together (the message shows them).
            InvalidMDPError: If a row does not sum to 1, or a value is not finite.
        """
        mats, eps = _as_matrix_list(P)
        A = len(mats)
        if A == 0:
            raise ShapeError("P must hold at least one action; got an empty list")
        S = mats[0].shape[0]
        for a, m in enumerate(mats):
            if m.shape != (S, S):
                raise ShapeError(
                    f"P[{a}] has shape {m.shape}; every P[a] must be S x S = ({S}, {S}) "
                    f"(shapes: {[mm.shape for mm in mats]})"
                )
        term = _terminal_mask(terminal, S)
        if action_mask is None:
            mask = np.ones((S, A), dtype=bool)
        else:
            mask = np.asarray(action_mask)
            if mask.dtype.kind not in "biu":
                raise InvalidMDPError(
                    f"action_mask must be a boolean (S, A) array; got dtype {mask.dtype}"
                )
            mask = mask.astype(bool)
            if mask.shape != (S, A):
                raise ShapeError(
                    f"action_mask has shape {mask.shape}; expected (S, A) = ({S}, {A})"
                )
        mask = mask & ~term[:, None]
        r_kind, r_data = _reward_arrays(R, S, A)
        counts = np.zeros((S, A), dtype=np.int64)
        per_action: list[
            tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]
        ] = []
        for a, m in enumerate(mats):
            keep = mask[:, a]
            rows_keep = sp.diags_array(keep.astype(np.float64)).tocsr()
            pa = sp.csr_array(rows_keep @ m)
            pa.sort_indices()
            row_of = np.repeat(np.arange(S), np.diff(pa.indptr))
            if r_kind == "sa":
                rew = np.asarray(r_data)[row_of, a]
            elif r_kind == "dense":
                rew = np.asarray(r_data)[a][row_of, pa.indices]
            else:
                ra = sp.csr_array(r_data[a])
                rew = np.asarray(ra[row_of, pa.indices]).ravel()
            per_action.append(
                (
                    pa.indptr.astype(np.int64),
                    pa.indices.astype(np.int64),
                    np.asarray(pa.data, dtype=np.float64),
                    np.asarray(rew, dtype=np.float64),
                )
            )
            counts[:, a] = np.diff(pa.indptr)
        indptr = np.concatenate([[0], np.cumsum(counts.ravel())])
        K = int(indptr[-1])
        nxt: NDArray[np.integer[Any]] = np.empty(K, dtype=np.int32 if S < 2**31 else np.int64)
        probs = np.empty(K)
        rewards = np.empty(K)
        for a, (ip, idx, data, rew) in enumerate(per_action):
            if len(idx) == 0:
                continue
            starts = indptr[np.arange(S) * A + a]
            pos = np.repeat(starts - ip[:-1], np.diff(ip)) + np.arange(len(idx))
            nxt[pos], probs[pos], rewards[pos] = idx, data, rew
        if eps > 0.0 and K:
            # Low-precision P (float32): each of a pair's n stored probabilities may be off by
            # one unit in the last place, so a sum within n * eps of 1 is stochastic to the
            # precision given; normalise it so the model is stochastic in float64.
            n_max = int(counts.max())
            tol = max(PROB_TOL, eps * n_max)
            sums = _segment_sum(probs, indptr)
            bad = mask.ravel() & (np.abs(sums - 1.0) > tol)
            if np.any(bad):
                s, a = divmod(int(np.flatnonzero(bad)[0]), A)
                lab_s = states[s] if states is not None and len(states) == S else s
                lab_a = actions[a] if actions is not None and len(actions) == A else a
                raise _sum_error(lab_s, lab_a, sums[s * A + a], tol)
            pos_sums = np.repeat(np.where(sums > 0, sums, 1.0), np.diff(indptr))
            probs = probs / pos_sums
        st = tuple(states) if states is not None else tuple(range(S))
        ac = tuple(actions) if actions is not None else tuple(range(A))
        if len(st) != S or len(ac) != A:
            raise ShapeError(f"got {len(st)} state and {len(ac)} action labels for S={S}, A={A}")
        if initial is None:
            init = (~term).astype(np.float64)
            init /= max(init.sum(), 1.0)
        else:
            init = _float_array(initial, "initial")
        return cls(
            states=st,
            actions=ac,
            gamma=gamma,
            terminal=term,
            action_mask=mask,
            indptr=indptr,
            next_states=nxt,
            probs=probs,
            rewards=rewards,
            initial=init,
            name=name,
            meta=dict(meta or {}),
        )

    @classmethod
    def from_gymnasium(cls, env: Any, gamma: float = 1.0, *, name: str | None = None) -> FiniteMDP:
        """Read the model of a Gymnasium toy-text environment (FrozenLake, CliffWalking, Taxi-v4).

        The env (or ``env.unwrapped``) must expose ``P[s][a] = [(prob, next_state,
        reward, terminated), ...]``. Duplicate outcomes are summed; a next state reached
        with ``terminated=True`` becomes a terminal state of the MDP (its own entries in
        ``P`` are ignored). Reaching that state with ``terminated=False`` from a state
        reachable from the start is refused as inconsistent; states that cannot be reached
        (Taxi's "already delivered" states) are kept, and there a move into a terminal
        state ends the episode. The start distribution is read from
        ``initial_state_distrib`` where the env has one (else uniform over S). Actions
        keep the env's index order and are labelled with Gymnasium's documented names
        where known (FrozenLake: left, down, right, up; CliffWalking: up, right, down,
        left; Taxi: south, north, east, west, pickup, dropoff), else 0..A-1.

        Args:
            env: A Gymnasium environment, or an id string for ``gymnasium.make``.
            gamma: Discount rate in [0, 1].
            name: A short name; default: the env's id.

        Raises:
            InvalidMDPError: If the env has no ``P`` or it is inconsistent.
        """
        if isinstance(env, str):
            import gymnasium as gym

            env_id = env
            try:
                env = gym.make(env_id)
            except Exception as e:  # gymnasium raises its own error types for unknown ids
                raise InvalidMDPError(
                    f"cannot make Gymnasium env {env_id!r}: {' '.join(str(e).split())}"
                ) from None
        else:
            spec = getattr(env, "spec", None)
            env_id = getattr(spec, "id", None) or type(env).__name__
        base = getattr(env, "unwrapped", env)
        P = getattr(base, "P", None)
        if P is None:
            raise InvalidMDPError(
                f"environment {env_id!r} has no transition model `P` (P[s][a] = [(prob, "
                "next_state, reward, terminated)]); only toy-text style envs such as "
                "FrozenLake-v1, CliffWalking-v1 or Taxi-v4 can be read as a FiniteMDP"
            )
        S = len(P)
        A = max(len(P[s]) for s in range(S))
        terminal_set: set[int] = set()
        for s in range(S):
            for a in range(len(P[s])):
                for out in P[s][a]:
                    if len(out) != 4:
                        raise InvalidMDPError(
                            f"{env_id}: P[{s}][{a}] holds {_fmt_items(out)}; expected (prob, "
                            "next_state, reward, terminated)"
                        )
                    if out[3]:
                        terminal_set.add(int(out[1]))
        init_d = getattr(base, "initial_state_distrib", None)
        init_arr = np.asarray(init_d, dtype=np.float64) if init_d is not None else None
        # A next state reached with terminated=True is terminal. A transition into it with
        # terminated=False is a contradiction only where it can happen: from states reachable
        # from the start (Taxi keeps unreachable "passenger already delivered" states).
        reachable = np.zeros(S, dtype=bool)
        frontier = (
            [int(x) for x in np.flatnonzero(init_arr > 0)]
            if init_arr is not None
            else list(range(S))
        )
        for s0 in frontier:
            reachable[s0] = True
        while frontier:
            s = int(frontier.pop())
            if s in terminal_set:
                continue
            for a in range(len(P[s])):
                for prob, nxt, _rew, _done in P[s][a]:
                    n = int(nxt)
                    if prob > 0 and not reachable[n]:
                        reachable[n] = True
                        frontier.append(n)
        dynamics: dict[int, dict[int, list[tuple[float, int, float]]]] = {}
        for s in range(S):
            if s in terminal_set:
                continue
            acts: dict[int, list[tuple[float, int, float]]] = {}
            for a in range(len(P[s])):
                outs = []
                for prob, nxt, rew, done in P[s][a]:
                    if prob == 0:
                        continue
                    if reachable[s] and int(nxt) in terminal_set and not done:
                        raise InvalidMDPError(
                            f"{env_id}: state {int(nxt)} is reached with terminated=True "
                            f"elsewhere but with terminated=False from P[{s}][{a}]"
                        )
                    outs.append((float(prob), int(nxt), float(rew)))
                acts[a] = outs
            dynamics[s] = acts
        for t in sorted(terminal_set):
            dynamics[t] = {}
        order = list(range(S))
        initial: Mapping[Hashable, float] | None = None
        if init_arr is not None:
            initial = {s: float(init_arr[s]) for s in order if init_arr[s] > 0}
        from policylab.mdp.gym_grid import gym_action_labels, gym_grid_layout

        labels = gym_action_labels(base, A)
        ordered = {s: {labels[a]: outs for a, outs in dynamics[s].items()} for s in order}

        return cls.from_dynamics(
            ordered,  # type: ignore[arg-type]
            gamma=gamma,
            terminal=sorted(terminal_set),
            actions=labels,
            initial=initial,
            name=name or str(env_id),
            grid=gym_grid_layout(base, S, A),
        )


def _segment_sum(values: NDArray[np.float64], indptr: NDArray[np.int64]) -> NDArray[np.float64]:
    """out[i] = sum(values[indptr[i]:indptr[i + 1]]) (0 for an empty segment)."""
    n = len(indptr) - 1
    out = np.zeros(n)
    nonempty = indptr[1:] > indptr[:-1]
    if values.size:
        out[nonempty] = np.add.reduceat(values, indptr[:-1][nonempty])
    return out


def _short(labels: Sequence[Hashable], limit: int = 12) -> str:
    items = [repr(x) for x in labels[:limit]]
    if len(labels) > limit:
        items.append(f"... ({len(labels)} in all)")
    return "[" + ", ".join(items) + "]"


def _initial_from(
    initial: Hashable | Mapping[Hashable, float] | None,
    states: Sequence[Hashable],
    s_index: Mapping[Hashable, int],
    term: NDArray[np.bool_],
) -> NDArray[np.float64]:
    S = len(states)
    init = np.zeros(S)
    if initial is None:
        init[~term] = 1.0
        init /= max(init.sum(), 1.0)
        return init
    if isinstance(initial, Mapping):
        for lab, pr in initial.items():
            if lab not in s_index:
                raise UnknownLabelError(f"initial distribution names unknown state {lab!r}")
            init[s_index[lab]] += float(pr)
        return init
    try:
        init[s_index[initial]] = 1.0
    except (KeyError, TypeError):
        raise UnknownLabelError(
            f"initial state {initial!r} is not a state; states are {_short(states)}"
        ) from None
    return init


def _float_array(x: Any, what: str) -> NDArray[np.float64]:
    """``x`` as a float64 array, or a policylab error naming ``what`` (no NumPy message)."""
    return check_float_array(x, what, error=InvalidMDPError)


def _eps_of(dtype: Any) -> float:
    """Machine epsilon of a floating dtype below float64 (0 for float64 and integers)."""
    dt = np.dtype(dtype)
    if dt.kind == "f" and dt.itemsize < 8:
        return float(np.finfo(dt).eps)
    return 0.0


def _is_matrix_sequence(x: Any) -> bool:
    """A list, a tuple or a 1-D object array (pymdptoolbox's convention) of matrices."""
    if isinstance(x, np.ndarray):
        return x.dtype == object and x.ndim == 1
    return isinstance(x, (list, tuple))


def _as_matrix_list(P: Any) -> tuple[list[Any], float]:
    """The A matrices of P (sparse CSR or dense float64) and the epsilon of P's precision."""
    if sp.issparse(P):
        raise ShapeError(
            "P as one sparse matrix is ambiguous; pass a list of A sparse S x S matrices"
        )
    if not _is_matrix_sequence(P) or not any(sp.issparse(m) for m in P):
        eps = _eps_of(getattr(P, "dtype", np.float64))
        if _is_matrix_sequence(P):
            eps = max([eps, *(_eps_of(getattr(m, "dtype", np.float64)) for m in P)])
        arr = _float_array(P, "P")
        if arr.ndim != 3:
            raise ShapeError(
                f"P must be (A, S, S) or a list of A S x S matrices; got shape {arr.shape}"
            )
        return [arr[a] for a in range(arr.shape[0])], eps
    mats: list[Any] = []
    eps = 0.0
    for a, m in enumerate(P):
        eps = max(eps, _eps_of(getattr(m, "dtype", np.float64)))
        if sp.issparse(m):
            if m.dtype.kind not in "biuf":
                raise InvalidMDPError(
                    f"P[{a}] must hold real numbers; got a sparse matrix of dtype {m.dtype}"
                )
            mats.append(sp.csr_array(m, dtype=np.float64))
        else:
            arr = _float_array(m, f"P[{a}]")
            if arr.ndim != 2:
                raise ShapeError(f"P[{a}] has shape {arr.shape}; expected an S x S matrix")
            mats.append(arr)
    return mats, eps


def _terminal_mask(terminal: Any, S: int) -> NDArray[np.bool_]:
    if terminal is None:
        return np.zeros(S, dtype=bool)
    arr = np.asarray(list(terminal) if not isinstance(terminal, np.ndarray) else terminal)
    if arr.dtype == bool:
        if arr.shape != (S,):
            raise ShapeError(f"terminal mask has shape {arr.shape}; expected ({S},)")
        return arr.copy()
    mask = np.zeros(S, dtype=bool)
    if arr.size:
        if arr.dtype.kind not in "iu":
            raise InvalidMDPError(
                f"terminal must be a boolean mask ({S},) or a list of state indices; got an "
                f"array of dtype {arr.dtype} ({arr.ravel()[:5].tolist()!r})"
            )
        idx = arr.astype(np.int64)
        if idx.min() < 0 or idx.max() >= S:
            raise InvalidMDPError(f"terminal indices must lie in [0, {S}); got {arr.tolist()}")
        mask[idx] = True
    return mask


def _reward_arrays(R: Any, S: int, A: int) -> tuple[str, Any]:
    if _is_matrix_sequence(R) and len(R) and (sp.issparse(R[0]) or np.ndim(R[0]) == 2):
        if len(R) != A or any(np.shape(m) != (S, S) for m in R):
            raise ShapeError(
                f"R as a list must hold A = {A} matrices of shape ({S}, {S}); got "
                f"{[np.shape(m) for m in R]}"
            )
        if any(sp.issparse(m) for m in R):
            for a, m in enumerate(R):
                if sp.issparse(m) and m.dtype.kind not in "biuf":
                    raise InvalidMDPError(
                        f"R[{a}] must hold real numbers; got a sparse matrix of dtype {m.dtype}"
                    )
            return "sparse", list(R)
        return "dense", np.stack([_float_array(m, f"R[{a}]") for a, m in enumerate(R)])
    arr = _float_array(R, "R")
    if arr.shape == (S, A):
        return "sa", arr
    if arr.shape == (A, S, S):
        return "dense", arr
    raise ShapeError(
        f"R has shape {arr.shape}; expected (S, A) = ({S}, {A}) or (A, S, S) = ({A}, {S}, {S}) "
        f"to match P of {A} actions over {S} states"
    )
