"""GAE and n-step returns against hand-computed arrays."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.deep import gae_advantages, n_step_targets
from policylab.exceptions import InvalidArgumentError


def test_gae_hand_computed_with_truncation_and_termination() -> None:
    # one env, 5 steps: episode A = steps 0,1 (truncated after step 1), episode B = steps 2,3,4
    # (terminated after step 3), step 4 starts episode C and is cut by the rollout end.
    r = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    v = np.array([0.5, 1.0, 1.5, 2.0, 2.5])
    nv = np.array(
        [1.0, 7.0, 2.0, 99.0, 3.0]
    )  # V(S'_t): 7 = V(last state of A), 99 ignored (terminal)
    term = np.array([False, False, False, True, False])
    trunc = np.array([False, True, False, False, False])
    g, lam = 0.9, 0.8
    d = [
        1 + 0.9 * 1.0 - 0.5,
        2 + 0.9 * 7.0 - 1.0,
        3 + 0.9 * 2.0 - 1.5,
        4 - 2.0,
        5 + 0.9 * 3.0 - 2.5,
    ]
    a4 = d[4]
    a3 = d[3]  # terminated: no carry from step 4
    a2 = d[2] + g * lam * a3
    a1 = d[1]  # truncated: no carry from step 2
    a0 = d[0] + g * lam * a1
    np.testing.assert_allclose(gae_advantages(r, v, nv, term, trunc, g, lam), [a0, a1, a2, a3, a4])


def test_gae_lambda_one_is_monte_carlo_and_zero_is_td() -> None:
    r = np.array([1.0, 0.0, 2.0])
    v = np.array([0.3, 0.2, 0.1])
    nv = np.array([0.2, 0.1, 0.0])
    term = np.array([False, False, True])
    trunc = np.zeros(3, dtype=bool)
    mc = gae_advantages(r, v, nv, term, trunc, 0.5, 1.0)
    np.testing.assert_allclose(mc, [1 + 0.25 * 2 - 0.3, 0.5 * 2 - 0.2, 2 - 0.1])
    td = gae_advantages(r, v, nv, term, trunc, 0.5, 0.0)
    np.testing.assert_allclose(td, [1 + 0.5 * 0.2 - 0.3, 0.5 * 0.1 - 0.2, 2 - 0.1])


def test_gae_vectorised_over_envs() -> None:
    rng = np.random.default_rng(1)
    T, N = 6, 3
    args = [rng.normal(size=(T, N)) for _ in range(3)]
    term, trunc = rng.random((T, N)) < 0.2, rng.random((T, N)) < 0.2
    both = gae_advantages(*args, term, trunc, 0.99, 0.95)
    for i in range(N):
        one = gae_advantages(*(a[:, i] for a in args), term[:, i], trunc[:, i], 0.99, 0.95)
        np.testing.assert_allclose(both[:, i], one)


def test_n_step_hand_computed() -> None:
    r = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    term = np.array([False, False, True, False, False, False])
    trunc = np.array([False, False, False, False, True, False])
    g = 0.5
    ret, disc, last = n_step_targets(r, term, trunc, g, 3)
    # step 0: 1 + .5*2 + .25*3, ends by termination at step 2 -> no bootstrap
    # step 3: 4 + .5*5, truncated at step 4 -> bootstrap gamma^2 from S' of step 4
    # step 5: only one step left in the array -> bootstrap gamma from S' of step 5
    np.testing.assert_allclose(ret, [2.75, 3.5, 3.0, 6.5, 5.0, 6.0])
    np.testing.assert_allclose(disc, [0.0, 0.0, 0.0, 0.25, 0.5, 0.5])
    np.testing.assert_array_equal(last, [2, 2, 2, 4, 4, 5])


def test_n_step_one_is_one_step_q_learning() -> None:
    r = np.array([1.0, 2.0, 3.0])
    term = np.array([False, False, True])
    ret, disc, last = n_step_targets(r, term, np.zeros(3, bool), 0.9, 1)
    np.testing.assert_allclose(ret, r)
    np.testing.assert_allclose(disc, [0.9, 0.9, 0.0])
    np.testing.assert_array_equal(last, [0, 1, 2])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"gamma": 1.5}, "gamma"), ({"gae_lambda": -0.1}, "gae_lambda")],
)
def test_gae_rejects_bad_arguments(kwargs: dict[str, float], match: str) -> None:
    args = {"gamma": 0.9, "gae_lambda": 0.9, **kwargs}
    z = np.zeros(3)
    with pytest.raises(InvalidArgumentError, match=match):
        gae_advantages(z, z, z, z.astype(bool), z.astype(bool), **args)
    with pytest.raises(InvalidArgumentError, match="next_values"):
        gae_advantages(z, z, np.zeros(4), z.astype(bool), z.astype(bool), 0.9, 0.9)


def test_n_step_rejects_bad_n() -> None:
    with pytest.raises(InvalidArgumentError, match="n must be"):
        n_step_targets([1.0], [False], [False], 0.9, 0)
