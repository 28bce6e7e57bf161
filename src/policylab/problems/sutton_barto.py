"""Sutton & Barto's (2nd ed.) planning classics.

The gridworlds of Examples 3.5 and 4.1, the gambler's problem (Example 4.3) and Jack's
car rental (Example 4.2).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import numpy as np

from policylab.exceptions import InvalidArgumentError
from policylab.mdp.finite import FiniteMDP
from policylab.mdp.grid import Cell, GridLayout, grid_mdp
from policylab.mdp.policy import Policy
from policylab.problems._poisson import poisson_pmf_and_tail
from policylab.problems.registry import register_problem

__all__ = [
    "GRIDWORLD_5X5_A",
    "GRIDWORLD_5X5_B",
    "gamblers_bold_policy",
    "gamblers_problem",
    "gridworld_4x4",
    "gridworld_5x5",
    "jacks_car_rental",
    "jacks_no_move_policy",
]

#: Example 3.5's special cells: A -> A' with +10 and B -> B' with +5 (row, column).
GRIDWORLD_5X5_A = ((0, 1), (4, 1), 10.0)
GRIDWORLD_5X5_B = ((0, 3), (2, 3), 5.0)


def gridworld_5x5(gamma: float = 0.9) -> FiniteMDP:
    """The gridworld of Sutton & Barto's Example 3.5 (Figures 3.2 and 3.5).

    A 5 x 5 grid of cells (row, column), row 0 at the top; actions up, down, left,
    right. A move off the grid leaves the agent in place with reward -1; every other
    move earns 0, except that from A = (0, 1) every action moves to A' = (4, 1) with
    reward +10, and from B = (0, 3) to B' = (2, 3) with +5. A continuing task with
    gamma = 0.9; the equiprobable random policy has v(A) = 8.8 and the optimum
    v_*(A) = 24.4.
    """
    (a, a2, ra), (b, b2, rb) = GRIDWORLD_5X5_A, GRIDWORLD_5X5_B

    def reward(frm: Cell, to: Cell, _kind: str) -> float:
        return -1.0 if frm == to else 0.0

    return grid_mdp(
        # A, A', B, B' are marked on the map (as the book draws them) for figures;
        # their dynamics come from ``jumps``.
        [".A.B.", ".....", "...b.", ".....", ".a..."],
        {".": "floor", "A": "A", "a": "A'", "B": "B", "b": "B'"},
        reward,
        terminal_kinds=(),
        jumps={a: (a2, ra), b: (b2, rb)},
        gamma=gamma,
        name="gridworld-5x5",
    )


def gridworld_4x4(gamma: float = 1.0, step_reward: float = -1.0) -> FiniteMDP:
    """The small gridworld of Sutton & Barto's Example 4.1 (Figure 4.1).

    A 4 x 4 grid; the top-left and bottom-right cells are terminal (the book draws its
    one terminal state twice). Actions up, down, left, right move deterministically, a
    move off the grid leaves the agent in place, and every transition earns -1. An
    undiscounted episodic task; the equiprobable random policy has values 0, -14, -20,
    -22 along the top row.
    """

    def reward(_frm: Cell, _to: Cell, _kind: str) -> float:
        return step_reward

    return grid_mdp(
        ["G...", "....", "....", "...G"],
        {".": "floor", "G": "goal"},
        reward,
        gamma=gamma,
        name="gridworld-4x4",
    )


def gamblers_problem(p_h: float = 0.4, goal: int = 100, gamma: float = 1.0) -> FiniteMDP:
    """The gambler's problem of Sutton & Barto's Example 4.3 (Figure 4.3).

    States are the gambler's capital 0..goal; 0 (ruin) and goal (win) are terminal. In
    state s the gambler stakes a in {1, ..., min(s, goal - s)} (action labels are the
    stakes); the coin comes up heads with probability ``p_h`` and the capital becomes
    s + a, else s - a. The reward is +1 on reaching the goal and 0 otherwise; gamma = 1,
    so v_*(s) is the probability of winning. A stake of 0, which the book allows,
    is left out: it never changes anything, and a policy that stakes 0 forever would
    never end the episode.

    Sets ``meta = {"x": capital per state, "xlabel": "Capital"}`` for figures.
    """
    if not 0.0 < float(p_h) < 1.0:
        raise InvalidArgumentError(f"p_h must lie strictly between 0 and 1; got {p_h!r}")
    if isinstance(goal, bool) or not isinstance(goal, int) or goal < 2:
        raise InvalidArgumentError(f"goal must be an integer >= 2; got {goal!r}")
    stakes = list(range(1, goal // 2 + 1))
    dynamics: dict[int, Any] = {0: {}, goal: {}}
    for s in range(1, goal):
        acts = {}
        for a in range(1, min(s, goal - s) + 1):
            win = s + a
            acts[a] = [(p_h, win, 1.0 if win == goal else 0.0), (1.0 - p_h, s - a, 0.0)]
        dynamics[s] = acts
    ordered: dict[Hashable, Any] = {s: dynamics[s] for s in range(goal + 1)}
    return FiniteMDP.from_dynamics(
        ordered,
        gamma=gamma,
        terminal=[0, goal],
        actions=stakes,
        name="gamblers-problem",
        meta={"x": list(range(goal + 1)), "xlabel": "Capital"},
    )


def gamblers_bold_policy(mdp: FiniteMDP) -> Policy:
    """Bold play: stake min(s, goal - s), everything that is needed or everything there is."""
    goal = max(int(s) for s in mdp.states)  # type: ignore[call-overload]
    return Policy.deterministic(
        mdp,
        {s: min(int(s), goal - int(s)) for s in mdp.states if 0 < int(s) < goal},  # type: ignore[call-overload]
    )


def _location_model(
    request_mean: float, return_mean: float, max_cars: int
) -> tuple[np.ndarray, np.ndarray]:
    """One location of Jack's: from m cars in the morning, the next evening's count.

    Returns ``L`` with L[m, j] = P(j cars at the end of the day | m cars), and ``M``
    with M[m, j] = E[rentals * 1{j cars at the end} | m cars], both (N+1, N+1).
    Requests beyond m are lost (rentals = min(requests, m)); returned cars beyond N
    go back to the nationwide company. Poisson tails are handled exactly.

    Both are products over the cars left after the rentals, ``left``:
    L = P_rent @ B and M = (P_rent * rentals) @ B, where P_rent[m, left] is the
    probability of renting m - left cars from m and B[left, j] that of ending the day
    with j cars from ``left``.
    """
    N = max_cars
    k = np.arange(N + 1)
    req_p, req_tail = poisson_pmf_and_tail(N + 1, request_mean)  # tail: P(requests >= k)
    ret_p, ret_tail = poisson_pmf_and_tail(N + 1, return_mean)  # P(returns >= k)
    rent = k[:, None] - k[None, :]  # rentals m - left, for m (rows) and left (columns)
    p_rent = np.where(rent >= 0, req_p[np.clip(rent, 0, N)], 0.0)
    p_rent[k, 0] = req_tail[k]  # left = 0: every request of m or more rents all m cars
    # end count j = min(left + returns, N)
    ret = k[None, :] - k[:, None]  # returns j - left, for left (rows) and j (columns)
    B = np.where(ret >= 0, ret_p[np.clip(ret, 0, N)], 0.0)
    B[:, N] = ret_tail[N - k]
    L = p_rent @ B
    M = (p_rent * np.maximum(rent, 0)) @ B
    return L, M


def jacks_car_rental(
    max_cars: int = 20,
    max_move: int = 5,
    rent_reward: float = 10.0,
    move_cost: float = 2.0,
    request_means: tuple[float, float] = (3.0, 4.0),
    return_means: tuple[float, float] = (3.0, 2.0),
    gamma: float = 0.9,
    *,
    post_decision: bool = False,
) -> Any:
    """Jack's car rental, Sutton & Barto's Example 4.2 (Figure 4.2).

    The model, as the book states it: a state (n1, n2) is the number of cars at each
    location at the end of a day (0..20 each, 441 states). Overnight Jack moves a in
    -5..5 cars from the first location to the second (negative: the other way) at
    $2 a car; a must not exceed the cars available (a <= n1, -a <= n2), and cars beyond
    20 at a location disappear. Next day requests and returns at the two locations are
    independent Poisson variables with means 3 and 4 (requests) and 3 and 2
    (returns); each car rented earns $10 and requests beyond the cars present are
    lost; cars returned become available the day after (they count in the end-of-day
    state, again capped at 20). gamma = 0.9, a continuing task.

    The transition probabilities are exact (Poisson tails are lumped into the
    boundary outcomes, not truncated). Each outcome's reward is the expected reward
    given (s, a, s'), so r(s, a) is exact and sampled rewards vary with the outcome.

    Action labels are the integers -5..5 (net cars moved to the second location);
    ``grid`` lays states out as a 21 x 21 array (row n1, column n2) with no moves,
    and ``meta["axis_labels"]`` names its axes.

    ``post_decision=True`` returns the same MDP as a
    :class:`~policylab.mdp.PostDecisionMDP`: the move takes (n1, n2) surely to the
    morning counts (m1, m2) = (min(n1 - a, N), min(n2 + a, N)) (the post-decision
    state) and earns the expected rentals' $10 less the moves' cost; the day then
    takes (m1, m2) to the evening counts by the product K_1 (x) K_2 of the two
    locations' (N+1) x (N+1) kernels. Its size grows as S * A + 2 (N + 1)^2 where the
    outcome table's grows as S^2 * A (it holds every (s, a, s')), so it reaches 10^6
    states (``max_cars=999``) in about 150 MB.
    """
    for name, val, lo in (("max_cars", max_cars, 1), ("max_move", max_move, 0)):
        if isinstance(val, bool) or not isinstance(val, int | np.integer) or val < lo:
            raise InvalidArgumentError(f"{name} must be an integer >= {lo}; got {val!r}")
    N, K = int(max_cars), int(max_move)
    for name, means in (("request_means", request_means), ("return_means", return_means)):
        if len(means) != 2 or not all(float(x) > 0 for x in means):
            raise InvalidArgumentError(
                f"{name} must be two Poisson means > 0 (one per location); got {means!r}"
            )
    L1, M1 = _location_model(request_means[0], return_means[0], N)
    L2, M2 = _location_model(request_means[1], return_means[1], N)
    E1 = M1.sum(axis=1)  # expected rentals from m cars
    E2 = M2.sum(axis=1)
    moves = np.arange(-K, K + 1)
    S, A, n = (N + 1) ** 2, len(moves), N + 1
    n1, n2 = np.divmod(np.arange(S), n)
    mask = (moves[None, :] <= n1[:, None]) & (-moves[None, :] <= n2[:, None])
    if post_decision:
        from policylab.mdp.postdecision import PostDecisionMDP

        mm1 = np.minimum(n1[:, None] - moves[None, :], N)
        mm2 = np.minimum(n2[:, None] + moves[None, :], N)
        ok = mask
        post = np.where(ok, np.clip(mm1, 0, N) * n + np.clip(mm2, 0, N), 0)
        reward = (
            rent_reward * (E1[np.clip(mm1, 0, N)] + E2[np.clip(mm2, 0, N)])
            - move_cost * np.abs(moves)[None, :]
        )
        return PostDecisionMDP(
            post,
            np.where(ok, reward, 0.0),
            (L1 / L1.sum(axis=1, keepdims=True), L2 / L2.sum(axis=1, keepdims=True)),
            gamma,
            action_mask=mask,
            states=_PairLabels(n),
            actions=tuple(int(a) for a in moves),
            name="jacks-car-rental",
            meta={"axis_labels": ("cars at first location", "cars at second location")},
        )
    if S * S * A > 200_000_000:
        raise InvalidArgumentError(
            f"jacks_car_rental(max_cars={N}) as an outcome table would hold about "
            f"{S * S * A:,} outcomes; pass post_decision=True for the same MDP in the "
            "post-decision form"
        )
    indptr = np.zeros(S * A + 1, dtype=np.int64)
    counts = np.where(mask.ravel(), S, 0)
    indptr[1:] = np.cumsum(counts)
    total = int(indptr[-1])
    next_states = np.empty(total, dtype=np.int32)
    probs = np.empty(total)
    rewards = np.empty(total)
    j1, j2 = np.divmod(np.arange(S), n)
    pos = 0
    for s in range(S):
        for ai, a in enumerate(moves):
            if not mask[s, ai]:
                continue
            m1, m2 = min(n1[s] - a, N), min(n2[s] + a, N)
            p = L1[m1, j1] * L2[m2, j2]
            # E[rentals | s, a, s'] = (M1 L2 + L1 M2) / (L1 L2)
            with np.errstate(invalid="ignore", divide="ignore"):
                rent = np.where(
                    p > 0, (M1[m1, j1] * L2[m2, j2] + L1[m1, j1] * M2[m2, j2]) / p, E1[m1] + E2[m2]
                )
            next_states[pos : pos + S] = np.arange(S)
            probs[pos : pos + S] = p / p.sum()
            rewards[pos : pos + S] = rent_reward * rent - move_cost * abs(int(a))
            pos += S
    states = tuple((int(x), int(y)) for x, y in zip(n1, n2, strict=True))
    init = np.zeros(S)
    init[states.index((N // 2, N // 2))] = 1.0
    return FiniteMDP(
        states=states,
        actions=tuple(int(a) for a in moves),
        gamma=gamma,
        terminal=np.zeros(S, dtype=bool),
        action_mask=mask,
        indptr=indptr,
        next_states=next_states,
        probs=probs,
        rewards=rewards,
        initial=init,
        name="jacks-car-rental",
        grid=GridLayout(shape=(n, n), cells=states, moves=()),
        meta={"axis_labels": ("cars at first location", "cars at second location")},
    )


class _PairLabels(Sequence[Hashable]):
    """The states (n1, n2) of Jack's car rental in index order, without a tuple of them."""

    def __init__(self, n: int) -> None:
        self._n = n

    def __len__(self) -> int:
        return self._n * self._n

    def __getitem__(self, i: Any) -> Any:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        j = range(len(self))[i]
        return (j // self._n, j % self._n)

    def index(self, value: Any, start: int = 0, stop: int | None = None) -> int:
        if (
            isinstance(value, tuple)
            and len(value) == 2
            and all(isinstance(x, int | np.integer) and 0 <= x < self._n for x in value)
        ):
            return int(value[0]) * self._n + int(value[1])
        raise ValueError(value)


def jacks_no_move_policy(mdp: FiniteMDP) -> Policy:
    """Jack's starting policy pi_0 of Figure 4.2: never move a car."""
    return Policy.deterministic(mdp, {s: 0 for s in mdp.states})


register_problem(
    gridworld_5x5,
    "S&B Example 3.5: 5x5 grid, A -> A' +10, B -> B' +5, -1 off the grid, gamma 0.9.",
    max_episode_steps=200,
    section="S&B 3.5",
)
register_problem(
    gridworld_4x4,
    "S&B Example 4.1: 4x4 grid, terminal corners, -1 per step, gamma 1.",
    max_episode_steps=200,
    section="S&B 4.1",
)
register_problem(
    gamblers_problem,
    "S&B Example 4.3: gambler's problem, stake to reach 100, heads with p_h = 0.4.",
    policies={"bold": gamblers_bold_policy},
    max_episode_steps=1000,
    section="S&B 4.3",
)
register_problem(
    jacks_car_rental,
    "S&B Example 4.2: Jack's car rental, 21x21 states, move -5..5 cars overnight.",
    policies={"no-move": jacks_no_move_policy},
    max_episode_steps=200,
    section="S&B 4.2",
)
