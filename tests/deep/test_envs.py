"""The vector envs the agents step: one copy of a vectorised env as the single env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl
from policylab.deep.common.envs import OneEnvVector


@pytest.mark.parametrize("env_id", ["CartPole-v1", "Acrobot-v1"])
def test_one_env_vector_steps_as_a_sync_vector_env_of_one(env_id: str) -> None:
    ours = pl.deep.make_vec_env(env_id, 1)
    assert isinstance(ours, OneEnvVector)
    ref = gym.vector.SyncVectorEnv([lambda: gym.make(env_id)])
    o1, _ = ours.reset(seed=3)
    o2, _ = ref.reset(seed=3)
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(1100):  # several episodes, so several next-step autoresets
        np.testing.assert_array_equal(o1, o2)
        assert o1.dtype == o2.dtype and o1.shape == (1, *ours.single_observation_space.shape)
        a = rng.integers(0, ours.single_action_space.n, 1)  # type: ignore[attr-defined]
        o1, r1, te1, tr1, _ = ours.step(a)
        o2, r2, te2, tr2, _ = ref.step(a)
        for x, y in ((r1, r2), (te1, te2), (tr1, tr2)):
            np.testing.assert_array_equal(x, y)
            assert x.dtype == y.dtype
        ends += int(te1[0] or tr1[0])
    assert ends >= 2
    assert pl.deep.common.envs.env_id_of(ours) == env_id
    ours.close()
