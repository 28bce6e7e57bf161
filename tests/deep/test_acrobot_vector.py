"""policylab's NumPy-vectorised Acrobot-v1 against Gymnasium's Acrobot, step by step."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl
from policylab.deep.common.envs import AcrobotVectorEnv
from policylab.exceptions import InvalidArgumentError


def test_same_observations_rewards_and_ends_as_gymnasium_bit_for_bit() -> None:
    n = 4
    venv = AcrobotVectorEnv(n)
    obs, _ = venv.reset(seed=0)
    singles = [gym.make("Acrobot-v1") for _ in range(n)]

    def start(i: int, e: gym.Env) -> np.ndarray:  # the single env in the copy's start state
        e.reset(seed=i)
        e.unwrapped.state = venv.state[:, i].astype(np.float32)  # type: ignore[attr-defined]
        return e.unwrapped._get_ob()  # type: ignore[attr-defined,no-any-return]

    for i, e in enumerate(singles):
        np.testing.assert_array_equal(start(i, e), obs[i])
    rng = np.random.default_rng(0)
    prev = np.zeros(n, dtype=bool)
    ends = {"terminated": 0, "truncated": 0}
    for _ in range(1100):  # past two time limits of 500 steps, with resets in between
        a = rng.choice(3, size=n, p=[0.45, 0.1, 0.45])
        obs, rew, term, trunc, _ = venv.step(a)
        for i, e in enumerate(singles):
            if prev[i]:  # next-step autoreset: this step only resets the copy
                expected = (start(i, e), 0.0, False, False)
            else:
                o, r, te, tr, _ = e.step(int(a[i]))
                expected = (o, r, te, tr)
            assert np.array_equal(obs[i], expected[0])
            assert (rew[i], term[i], trunc[i]) == expected[1:]
        ends["terminated"] += int(term.sum())
        ends["truncated"] += int(trunc.sum())
        prev = term | trunc
    assert ends["truncated"] >= n


def test_seeding_and_errors() -> None:
    a, b = AcrobotVectorEnv(3), AcrobotVectorEnv(3)
    np.testing.assert_array_equal(a.reset(seed=5)[0], b.reset(seed=5)[0])
    assert not np.array_equal(a.reset(seed=5)[0], b.reset(seed=6)[0])
    with pytest.raises(InvalidArgumentError, match="integers in 0..2"):
        a.step(np.array([0, 1, 3]))
    with pytest.raises(InvalidArgumentError, match="3 integers"):
        a.step(np.array([0, 1]))


def test_agents_get_it_for_acrobot_and_train_on_it() -> None:
    venv = pl.deep.make_vec_env("Acrobot-v1", 2)
    assert isinstance(venv, AcrobotVectorEnv) and venv.single_observation_space.shape == (6,)
    agent = pl.deep.PPO("Acrobot-v1", n_envs=2, n_steps=128, n_epochs=1, seed=0)
    agent.learn(1100)
    assert agent.num_timesteps >= 1100 and agent.episodes >= 2  # each copy hit 500 steps
    returns = pl.deep.evaluate(agent, episodes=3, seed=0)
    assert returns.shape == (3,) and np.all(returns >= -500)


def test_scalar_acrobot_steps_as_gymnasium_bit_for_bit() -> None:
    from policylab.deep.common.envs import ScalarAcrobotEnv

    ours = gym.make(dataclasses.replace(gym.spec("Acrobot-v1"), entry_point=ScalarAcrobotEnv))
    ref = gym.make("Acrobot-v1")
    assert isinstance(ours.unwrapped, ScalarAcrobotEnv)
    rng = np.random.default_rng(1)
    ends = 0
    for episode in range(12):  # terminations, and time limits while random
        o1, _ = ours.reset(seed=episode)
        o2, _ = ref.reset(seed=episode)
        assert np.array_equal(o1, o2)
        done = False
        while not done:
            # mostly torque along the second joint's velocity (swings up), else random;
            # the last two episodes random only (they run into the time limit)
            swing = episode < 10 and rng.random() < 0.7
            a = 2 * int(o1[5] > 0) if swing else int(rng.integers(3))
            o1, r1, te1, tr1, _ = ours.step(a)
            o2, r2, te2, tr2, _ = ref.step(a)
            assert o1.dtype == o2.dtype and np.array_equal(o1, o2)
            assert (r1, te1, tr1) == (r2, te2, tr2) and type(r1) is type(r2)
            assert np.array_equal(ours.unwrapped.state, ref.unwrapped.state)  # type: ignore[attr-defined]
            done = te1 or tr1
            ends += te1
    assert ends >= 8 and not te1 and tr1  # whole episodes of both kinds
