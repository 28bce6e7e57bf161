"""Returns against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError


def test_discounted_return_by_hand():
    # G_0 = 1 + 0.5 * 2 + 0.25 * 3 = 2.75
    assert pl.discounted_return([1, 2, 3], 0.5) == pytest.approx(2.75)
    assert pl.discounted_return([1, 2, 3], 1.0) == 6.0
    assert pl.discounted_return([1, 2, 3], 0.0) == 1.0
    assert pl.discounted_return([], 0.9) == 0.0


def test_returns_to_go_by_hand():
    # the notes' sample episode on the slippery gridworld: -1, -1, -1, +10 with gamma 1
    np.testing.assert_allclose(pl.returns_to_go([-1, -1, -1, 10], 1.0), [7, 8, 9, 10])
    g = 0.9
    r = [0.0, 0.0, 1.0]
    np.testing.assert_allclose(pl.returns_to_go(r, g), [g * g, g, 1.0])
    rng = np.random.default_rng(0)
    r = rng.normal(size=50)
    G = pl.returns_to_go(r, 0.95)
    for t in range(50):
        assert G[t] == pytest.approx(sum(0.95**k * r[t + k] for k in range(50 - t)))
        assert G[t] == pytest.approx(pl.discounted_return(r[t:], 0.95))


@pytest.mark.parametrize("bad", [[[1, 2]], [1, float("nan")], "abc"])
def test_bad_rewards(bad):
    with pytest.raises(InvalidArgumentError):
        pl.discounted_return(bad, 0.9)


def test_bad_gamma():
    with pytest.raises(InvalidArgumentError, match=r"gamma must be in \[0, 1\]"):
        pl.returns_to_go([1.0], 1.1)
