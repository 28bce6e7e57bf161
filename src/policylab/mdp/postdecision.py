"""MDPs with a post-decision state: the action moves the state, then chance moves it on.

Many decision problems split each step in two. The action takes the state s, surely,
to a post-decision state y = f(s, a) (the stock on hand after an order; the cars at
each location after the overnight moves) and earns r(s, a); then chance moves y to
the next state s' with a kernel K(s' | y) that does not depend on the action (the
day's demand; the day's rentals and returns). Sutton & Barto (section 6.8) call y an
afterstate; Powell's *Approximate Dynamic Programming* (chapter 4) builds on the same
split. Then

    p(s' | s, a) = K(s' | f(s, a)),    E[v(S_{t+1}) | s, a] = (K v)(f(s, a)),

and a Bellman backup costs one application of K (once per post-decision state, not
once per (state, action)) plus an O(S * A) maximum:

    (T v)(s) = max_{a in A(s)} r(s, a) + gamma (K v)(f(s, a)).

:class:`PostDecisionMDP` keeps the model in that form: ``post`` (f, an (S, A) index
array), ``reward`` (r, (S, A)), the action sets and the kernel K as a
:class:`PostDecisionKernel`: a dense or sparse (Y, S) matrix, or a Kronecker product
of small factors when the state has independent parts (Jack's two locations), in
which case K v is a few small matrix products and K itself is never formed. Its size
is that of the (S, A) arrays plus the kernel's, where the outcome table of the same
MDP as a :class:`~policylab.mdp.finite.FiniteMDP` holds one entry per (s, a, s').
:meth:`PostDecisionMDP.to_finite_mdp` gives that table for sizes where it fits.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from policylab.exceptions import (
    InvalidArgumentError,
    InvalidMDPError,
    ShapeError,
    UnknownLabelError,
)
from policylab.mdp.finite import PROB_TOL, FiniteMDP
from policylab.validation import check_gamma

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["PostDecisionKernel", "PostDecisionMDP"]

#: :meth:`PostDecisionMDP.to_finite_mdp` refuses tables with more outcomes than this
#: unless told otherwise (each outcome takes 20 bytes).
MAX_TABLE_OUTCOMES = 50_000_000


def _as_matrix(m: Any, what: str) -> NDArray[np.float64] | sp.csr_array:
    """A dense float64 array or a CSR array of a probability matrix, checked."""
    if sp.issparse(m):
        mat: Any = sp.csr_array(m, dtype=np.float64)
        mat.sum_duplicates()
        mat.eliminate_zeros()
        data = mat.data
    else:
        try:
            mat = np.ascontiguousarray(m, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidMDPError(
                f"{what} must be a matrix of numbers; got {type(m).__name__}"
            ) from exc
        data = mat
    if mat.ndim != 2 or 0 in mat.shape:
        raise ShapeError(f"{what} must be a non-empty 2-D matrix; got shape {mat.shape}")
    if not np.all(np.isfinite(data)) or np.any(data < 0):
        raise InvalidMDPError(
            f"{what} has negative or non-finite entries; probabilities must be >= 0"
        )
    sums = np.asarray(mat.sum(axis=1)).ravel()
    bad = np.flatnonzero(np.abs(sums - 1.0) > PROB_TOL)
    if bad.size:
        raise InvalidMDPError(
            f"row {int(bad[0])} of {what} sums to {sums[bad[0]]:.6g}; each row (a "
            "post-decision state's distribution over next states) must sum to 1"
        )
    return mat


class PostDecisionKernel:
    """The kernel K(s' | y) from post-decision states y to next states s'.

    Either one (Y, S) matrix (dense or scipy sparse) or, for a state made of independent
    parts, the Kronecker product K = K_1 (x) K_2 (x) ... of per-part matrices (Y_i, S_i):
    states and post-decision states are then numbered in row-major order of their parts
    (s = s_1 S_2 + s_2 for two parts) and K(s' | y) = prod_i K_i(s'_i | y_i).

    Args:
        *factors: One matrix, or the factors of a Kronecker product, each row-stochastic.

    Raises:
        InvalidMDPError: If a matrix has negative or non-finite entries or a row that
            does not sum to 1.
    """

    def __init__(self, *factors: Any) -> None:
        if not factors:
            raise InvalidMDPError("a kernel needs at least one matrix")
        if len(factors) == 1 and isinstance(factors[0], (list, tuple)):
            factors = tuple(factors[0])
        many = len(factors) > 1
        self.factors: tuple[Any, ...] = tuple(
            _as_matrix(f, f"kernel factor {i}" if many else "the kernel")
            for i, f in enumerate(factors)
        )
        self.shape = (
            int(np.prod([f.shape[0] for f in self.factors])),
            int(np.prod([f.shape[1] for f in self.factors])),
        )

    @property
    def n_post(self) -> int:
        """Y, the number of post-decision states."""
        return self.shape[0]

    @property
    def n_states(self) -> int:
        """S, the number of next states."""
        return self.shape[1]

    @property
    def nbytes(self) -> int:
        """Bytes held by the factors."""
        total = 0
        for f in self.factors:
            total += (
                f.data.nbytes + f.indices.nbytes + f.indptr.nbytes if sp.issparse(f) else f.nbytes
            )
        return total

    def expect(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """(K v)(y) = sum_s' K(s' | y) v(s') = E[v(S') | y] for every post-decision state y.

        With factors, K v is computed one part at a time (for two parts, K_1 V K_2^T
        with V the (S_1, S_2) reshaping of v), never forming K.
        """
        if len(self.factors) == 1:
            return np.asarray(self.factors[0] @ v)
        if len(self.factors) == 2:
            k1, k2 = self.factors
            V = v.reshape(k1.shape[1], k2.shape[1])
            left = np.asarray(k1 @ V)  # (Y_1, S_2)
            return np.ascontiguousarray(np.asarray(k2 @ left.T).T).reshape(-1)
        x = v.reshape([f.shape[1] for f in self.factors])
        for i, f in enumerate(self.factors):
            moved = np.moveaxis(x, i, 0)
            rest = moved.shape[1:]
            out = np.asarray(f @ moved.reshape(moved.shape[0], -1))
            x = np.moveaxis(out.reshape((f.shape[0], *rest)), 0, i)
        return np.ascontiguousarray(x).reshape(-1)

    def row_counts(self) -> NDArray[np.int64]:
        """The number of next states with K(s' | y) > 0, for each y (Y,)."""
        out = np.ones(1, dtype=np.int64)
        for f in self.factors:
            c = np.diff(f.indptr) if sp.issparse(f) else np.count_nonzero(f, axis=1)
            out = np.multiply.outer(out, c.astype(np.int64)).reshape(-1)
        return out

    def to_csr(self) -> sp.csr_array:
        """K as one (Y, S) CSR matrix, exact zeros left out (the Kronecker product formed)."""
        mats = [sp.csr_array(f) for f in self.factors]
        out = mats[0]
        for m in mats[1:]:
            out = sp.csr_array(sp.kron(out, m, format="csr"))
        out.eliminate_zeros()
        out.sort_indices()
        return out

    def dense_rows(self, ys: NDArray[np.int64]) -> NDArray[np.float64]:
        """The rows K(. | y) of the given post-decision states, dense (len(ys), S)."""
        if len(self.factors) == 1:
            f = self.factors[0]
            return np.asarray(f[ys].toarray() if sp.issparse(f) else f[ys])
        dims = [f.shape[0] for f in self.factors]
        parts = np.unravel_index(ys, dims)
        out = np.ones((len(ys), 1))
        for f, idx in zip(self.factors, parts, strict=True):
            rows = np.asarray(f[idx].toarray() if sp.issparse(f) else f[idx])
            out = (out[:, :, None] * rows[:, None, :]).reshape(len(ys), -1)
        return out

    def __repr__(self) -> str:
        kinds = " (x) ".join(
            f"{'sparse' if sp.issparse(f) else 'dense'} {f.shape[0]}x{f.shape[1]}"
            for f in self.factors
        )
        return f"PostDecisionKernel({kinds})"


class _IndexLabels(Sequence[Hashable]):
    """The labels 0..n-1 of a model built without labels (a cheap sequence)."""

    def __init__(self, n: int) -> None:
        self._n = n

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, i: Any) -> Any:
        return range(self._n)[i]

    def index(self, value: Any, start: int = 0, stop: int | None = None) -> int:
        if (
            isinstance(value, (int, np.integer))
            and not isinstance(value, bool)
            and 0 <= value < self._n
        ):
            return int(value)
        raise ValueError(value)


class PostDecisionMDP:
    """A finite MDP whose action moves the state surely to y = f(s, a), then chance to s'.

    p(s' | s, a) = K(s' | f(s, a)) and the expected reward is r(s, a) (see the module
    docstring). A continuing task (no terminal states); the solvers need gamma < 1.

    Args:
        post: (S, A) integer array: the post-decision state f(s, a) in 0..Y-1 (entries
            of unavailable actions are ignored).
        reward: (S, A) expected reward r(s, a) (entries of unavailable actions ignored).
        kernel: A :class:`PostDecisionKernel`, or what its constructor takes (one
            (Y, S) matrix, or a tuple of Kronecker factors).
        gamma: Discount rate in [0, 1].
        action_mask: (S, A) booleans, True where a is in A(s); default all True.
        states: State labels (default 0..S-1); any sequence of distinct hashables.
        actions: Action labels (default 0..A-1).
        name: A short name for messages.
        meta: Problem-specific facts for displays (never read by solvers).

    Raises:
        ShapeError: If the arrays' shapes disagree.
        InvalidMDPError: If a post-decision index is out of range on an available
            action, a reward there is not finite, a state has no action, or the kernel
            is not row-stochastic.
    """

    def __init__(
        self,
        post: ArrayLike,
        reward: ArrayLike,
        kernel: PostDecisionKernel | Any,
        gamma: float,
        *,
        action_mask: ArrayLike | None = None,
        states: Sequence[Hashable] | None = None,
        actions: Sequence[Hashable] | None = None,
        name: str = "post-decision-mdp",
        meta: Mapping[str, Any] | None = None,
    ) -> None:
        self.kernel = (
            kernel if isinstance(kernel, PostDecisionKernel) else PostDecisionKernel(kernel)
        )
        f = np.asarray(post)
        if f.ndim != 2 or 0 in f.shape:
            raise ShapeError(f"post must be a non-empty (S, A) array; got shape {f.shape}")
        if f.dtype.kind not in "iu":
            raise InvalidMDPError(
                f"post must hold integer post-decision state indices; got dtype {f.dtype}"
            )
        S, A = f.shape
        Y = self.kernel.n_post
        if self.kernel.n_states != S:
            raise ShapeError(
                f"the kernel maps {Y} post-decision states to {self.kernel.n_states} states; "
                f"post has {S} states (rows)"
            )
        mask = np.ones((S, A), dtype=bool) if action_mask is None else np.asarray(action_mask)
        if mask.shape != (S, A) or mask.dtype != np.bool_:
            raise ShapeError(
                f"action_mask must be an (S, A) = ({S}, {A}) boolean array; got shape "
                f"{mask.shape} and dtype {mask.dtype}"
            )
        r = np.asarray(reward, dtype=np.float64)
        if r.shape != (S, A):
            raise ShapeError(f"reward must have shape (S, A) = ({S}, {A}); got {r.shape}")
        self.states: Sequence[Hashable] = _IndexLabels(S) if states is None else states
        self.actions: Sequence[Hashable] = tuple(range(A)) if actions is None else tuple(actions)
        if len(self.states) != S or len(self.actions) != A:
            raise ShapeError(
                f"got {len(self.states)} state labels and {len(self.actions)} action labels "
                f"for an (S, A) = ({S}, {A}) model"
            )
        empty = np.flatnonzero(~mask.any(axis=1))
        if empty.size:
            raise InvalidMDPError(
                f"state {self.states[int(empty[0])]!r} has no available action; every state "
                "of a post-decision MDP needs one (it has no terminal states)"
            )
        bad = mask & ((f < 0) | (f >= Y))
        if bad.any():
            s, a = map(int, np.argwhere(bad)[0])
            raise InvalidMDPError(
                f"f(s={self.states[s]!r}, a={self.actions[a]!r}) = {int(f[s, a])} is not a "
                f"post-decision state; expected an index in 0..{Y - 1}"
            )
        bad = mask & ~np.isfinite(r)
        if bad.any():
            s, a = map(int, np.argwhere(bad)[0])
            raise InvalidMDPError(
                f"r(s={self.states[s]!r}, a={self.actions[a]!r}) = {r[s, a]!r}; rewards of "
                "available actions must be finite"
            )
        self.gamma = check_gamma(gamma)
        self.action_mask: NDArray[np.bool_] = np.ascontiguousarray(mask)
        self.post: NDArray[np.int64] = np.ascontiguousarray(np.where(mask, f, 0), dtype=np.int64)
        self.reward: NDArray[np.float64] = np.ascontiguousarray(np.where(mask, r, 0.0))
        self.terminal: NDArray[np.bool_] = np.zeros(S, dtype=bool)
        self.name = name
        self.meta: Mapping[str, Any] = dict(meta or {})

    # ---------------------------------------------------------------- sizes and labels
    @property
    def n_states(self) -> int:
        """S."""
        return int(self.post.shape[0])

    @property
    def n_actions(self) -> int:
        """A."""
        return int(self.post.shape[1])

    @property
    def n_post(self) -> int:
        """Y, the number of post-decision states."""
        return self.kernel.n_post

    @property
    def expected_reward(self) -> NDArray[np.float64]:
        """r(s, a), (S, A) (0 on unavailable actions), as on a FiniteMDP."""
        return self.reward

    @property
    def nbytes(self) -> int:
        """Bytes held by the model's arrays and kernel."""
        return int(
            self.post.nbytes + self.reward.nbytes + self.action_mask.nbytes + self.kernel.nbytes
        )

    @cached_property
    def _state_index(self) -> dict[Hashable, int]:
        return {lab: i for i, lab in enumerate(self.states)}

    def state_index(self, label: Hashable) -> int:
        """The index of a state label."""
        if isinstance(self.states, tuple | list):
            if label in self._state_index:
                return self._state_index[label]
        else:  # a sequence of its own (labels computed from the index): its own index()
            try:
                return int(self.states.index(label))
            except (ValueError, TypeError):
                pass
        raise UnknownLabelError(f"unknown state {label!r} in {self.name!r}")

    def action_index(self, label: Hashable) -> int:
        """The index of an action label."""
        try:
            return self.actions.index(label)
        except ValueError:
            raise UnknownLabelError(
                f"unknown action {label!r} in {self.name!r}; actions are {list(self.actions)!r}"
            ) from None

    def available_actions(self, state: Hashable) -> list[Hashable]:
        """A(s): the labels of the actions available in ``state``."""
        s = self.state_index(state)
        return [self.actions[int(a)] for a in np.flatnonzero(self.action_mask[s])]

    # ---------------------------------------------------------------- the tabular model
    @property
    def n_outcomes(self) -> int:
        """The number of (s, a, s') outcomes of the same MDP as an outcome table."""
        counts = self.kernel.row_counts()
        return int(counts[self.post[self.action_mask]].sum())

    def to_finite_mdp(self, *, max_outcomes: int = MAX_TABLE_OUTCOMES) -> FiniteMDP:
        """The same MDP as a :class:`~policylab.mdp.finite.FiniteMDP` (an outcome table).

        Each available (s, a) gets the outcomes (K(s' | f(s, a)), s', r(s, a)) for every
        s' with K(s' | f(s, a)) > 0; every solver of the tabular model then finds the
        same v_* and optimal policies.

        Args:
            max_outcomes: Refuse tables with more outcomes than this.

        Raises:
            InvalidArgumentError: If the table would hold more than ``max_outcomes``.
        """
        S, A = self.n_states, self.n_actions
        K = self.kernel.to_csr()
        lengths = np.where(self.action_mask, np.diff(K.indptr)[self.post], 0).reshape(-1)
        total = int(lengths.sum())
        if total > max_outcomes:
            raise InvalidArgumentError(
                f"{self.name!r} as an outcome table would hold {total:,} outcomes "
                f"(> max_outcomes = {max_outcomes:,}); solve the post-decision model itself"
            )
        indptr = np.zeros(S * A + 1, dtype=np.int64)
        np.cumsum(lengths, out=indptr[1:])
        live = np.flatnonzero(self.action_mask.reshape(-1))
        rows = K[self.post.reshape(-1)[live]]
        rewards = np.repeat(self.reward.reshape(-1)[live], np.diff(rows.indptr))
        return FiniteMDP(
            states=tuple(self.states),
            actions=tuple(self.actions),
            gamma=self.gamma,
            terminal=np.zeros(S, dtype=bool),
            action_mask=self.action_mask.copy(),
            indptr=indptr,
            next_states=rows.indices.astype(np.int32 if S < 2**31 else np.int64),
            probs=np.asarray(rows.data, dtype=np.float64),
            rewards=rewards,
            initial=np.full(S, 1.0 / S),
            name=self.name,
            meta=dict(self.meta),
        )

    def __repr__(self) -> str:
        return (
            f"PostDecisionMDP({self.name!r}, states={self.n_states:,}, actions={self.n_actions}, "
            f"post-decision states={self.n_post:,}, gamma={self.gamma:g}, {self.kernel!r})"
        )
