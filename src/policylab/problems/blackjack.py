"""Blackjack as an exact finite MDP (Sutton & Barto Example 5.1; Gymnasium Blackjack-v1).

The rules are Gymnasium's ``Blackjack-v1`` with ``sab=True`` (Sutton & Barto's): an
infinite deck (each card drawn independently: ace 1/13, 2..9 1/13 each, ten-valued
4/13); the player sees their sum, the dealer's showing card and whether they hold a
usable ace (an ace counted as 11 without busting); they hit or stick; going over 21
loses (-1); on sticking the dealer draws to 17 or more (standing on soft 17) and the
higher sum wins (+1 / -1, equal sums draw 0). A natural (ace and ten as the first two
cards) wins +1 unless the dealer also has one (draw), and the player may still hit it.

Gymnasium's observation ``(player_sum, dealer_card, usable_ace)`` is the state label,
except that a natural is its own state ``(21, dealer_card, "natural")``: it is scored
differently from a soft 21 reached by hitting, so merging the two would not be Markov.
(A Gymnasium agent sees both as ``(21, d, 1)``; sticking is optimal in both.)
"""

from __future__ import annotations

from collections.abc import Hashable
from functools import cache

from policylab.mdp.finite import FiniteMDP
from policylab.mdp.policy import Policy
from policylab.problems.registry import register_problem

__all__ = ["BLACKJACK_CARDS", "blackjack", "blackjack_stick_on_20_policy"]

#: Card values of the infinite deck and their probabilities.
BLACKJACK_CARDS: tuple[tuple[int, float], ...] = (
    *((c, 1 / 13) for c in range(1, 10)),
    (10, 4 / 13),
)

_END = "end"
_BUST = 0
_NATURAL = -1


def _score(raw: int, has_ace: bool) -> tuple[int, bool]:
    """(hand total, usable ace): an ace counts 11 when that does not bust."""
    if has_ace and raw + 10 <= 21:
        return raw + 10, True
    return raw, False


@cache
def _dealer_from(raw: int, has_ace: bool) -> dict[int, float]:
    """Distribution of the dealer's final total (0 = bust) from a hand (raw sum, ace)."""
    total, _ = _score(raw, has_ace)
    if raw > 21:
        return {_BUST: 1.0}
    if total >= 17:
        return {total: 1.0}
    out: dict[int, float] = {}
    for c, p in BLACKJACK_CARDS:
        for final, q in _dealer_from(raw + c, has_ace or c == 1).items():
            out[final] = out.get(final, 0.0) + p * q
    return out


@cache
def _dealer_outcomes(showing: int) -> dict[int, float]:
    """Final dealer totals given the showing card, with ``_NATURAL`` for a natural."""
    out: dict[int, float] = {}
    for hidden, p in BLACKJACK_CARDS:
        if {showing, hidden} == {1, 10}:
            out[_NATURAL] = out.get(_NATURAL, 0.0) + p
            continue
        for final, q in _dealer_from(showing + hidden, showing == 1 or hidden == 1).items():
            out[final] = out.get(final, 0.0) + p * q
    return out


def _cmp(a: int, b: int) -> float:
    return float(a > b) - float(a < b)


def _stick(player: int, natural: bool, showing: int) -> list[tuple[float, Hashable, float]]:
    rewards: dict[float, float] = {}
    for final, p in _dealer_outcomes(showing).items():
        if natural:
            r = 0.0 if final == _NATURAL else 1.0
        elif final == _NATURAL:
            r = _cmp(player, 21)
        else:
            r = _cmp(player, final)  # a bust dealer has total 0
        rewards[r] = rewards.get(r, 0.0) + p
    return [(p, _END, r) for r, p in sorted(rewards.items())]


def _hit(raw: int, has_ace: bool, showing: int) -> list[tuple[float, Hashable, float]]:
    out: dict[tuple[Hashable, float], float] = {}
    for c, p in BLACKJACK_CARDS:
        raw2, ace2 = raw + c, has_ace or c == 1
        if raw2 > 21:
            key: tuple[Hashable, float] = (_END, -1.0)
        else:
            total, usable = _score(raw2, ace2)
            key = ((total, showing, usable), 0.0)
        out[key] = out.get(key, 0.0) + p
    return [(p, s, r) for (s, r), p in out.items()]


def blackjack() -> FiniteMDP:
    """Blackjack (Gymnasium Blackjack-v1, ``sab=True``) as an exact finite MDP.

    States ``(player_sum, dealer_card, usable_ace)`` for hard totals 4..21 and soft
    totals 12..21 against dealer cards 1 (ace) .. 10, the naturals ``(21, d,
    "natural")``, and the terminal state ``"end"``; actions ``"stick"`` (0) and
    ``"hit"`` (1) in Gymnasium's order. gamma = 1; the start distribution is that of
    the first two cards. ``meta["blackjack"]`` is True (displays draw the two usable-ace
    panels of Sutton & Barto Figure 5.2).
    """
    dynamics: dict[Hashable, dict[Hashable, list[tuple[float, Hashable, float]]]] = {}
    for showing in range(1, 11):
        for usable in (False, True):
            for total in range(12 if usable else 4, 22):
                raw = total - 10 if usable else total
                dynamics[(total, showing, usable)] = {
                    "stick": _stick(total, False, showing),
                    "hit": _hit(raw, usable, showing),
                }
        dynamics[(21, showing, "natural")] = {
            "stick": _stick(21, True, showing),
            "hit": _hit(11, True, showing),
        }
    initial: dict[Hashable, float] = {}
    for showing, pd in BLACKJACK_CARDS:
        for c1, p1 in BLACKJACK_CARDS:
            for c2, p2 in BLACKJACK_CARDS:
                if {c1, c2} == {1, 10}:
                    s: Hashable = (21, showing, "natural")
                else:
                    total, usable = _score(c1 + c2, 1 in (c1, c2))
                    s = (total, showing, usable)
                initial[s] = initial.get(s, 0.0) + pd * p1 * p2
    return FiniteMDP.from_dynamics(
        dynamics,
        gamma=1.0,
        terminal=[_END],
        actions=["stick", "hit"],
        initial=initial,
        name="blackjack",
        meta={"blackjack": True},
    )


def blackjack_stick_on_20_policy(mdp: FiniteMDP) -> Policy:
    """Sutton & Barto's fixed policy of Example 5.1: stick on 20 or 21, else hit."""
    return Policy.deterministic(
        mdp,
        {
            s: ("stick" if isinstance(s, tuple) and s[0] >= 20 else "hit")
            for s in mdp.states
            if s != _END
        },
    )


register_problem(
    blackjack,
    "Blackjack (S&B Ex. 5.1; Gymnasium Blackjack-v1 rules, sab=True), infinite deck, exact.",
    policies={"stick-on-20": blackjack_stick_on_20_policy},
    max_episode_steps=100,
    section="S&B 5.1",
)
