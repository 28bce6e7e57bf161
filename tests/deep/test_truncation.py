"""Regression: a time limit (truncation) bootstraps, a termination does not, in PPO and DQN."""

from __future__ import annotations

import numpy as np
import torch
from deep_testenvs import counting_vec_env

import policylab as pl


def _constant_value(agent: pl.deep.PPO, value: float) -> None:
    with torch.no_grad():
        agent.net.value_head.weight.zero_()
        agent.net.value_head.bias.fill_(value)


def test_ppo_truncated_episodes_bootstrap_from_the_last_state() -> None:
    # reward 1 forever, gamma 0.9: the true value is 10 everywhere. With V = 10 and a
    # correct bootstrap at the 5-step time limit every advantage is exactly 0; treating
    # the limit as a termination would give 1 - 10 = -9 on the last step of each episode.
    agent = pl.deep.PPO(
        counting_vec_env(2, limit=5), n_envs=2, n_steps=23, gamma=0.9, gae_lambda=1.0
    )
    _constant_value(agent, 10.0)
    agent._reset_envs()
    agent._collect()
    buf = agent.buffer
    assert buf.truncated.sum() >= 6 and not buf.terminated.any()
    np.testing.assert_allclose(buf.advantages[buf.valid], 0.0, atol=1e-5)
    np.testing.assert_allclose(buf.returns[buf.valid], 10.0, atol=1e-5)


def test_ppo_terminated_episodes_do_not_bootstrap() -> None:
    agent = pl.deep.PPO(
        counting_vec_env(2, limit=50, terminate_at=5),
        n_envs=2,
        n_steps=12,
        gamma=0.9,
        gae_lambda=0.0,
    )
    _constant_value(agent, 10.0)
    agent._reset_envs()
    agent._collect()
    buf = agent.buffer
    last = buf.terminated & buf.valid
    assert last.sum() == 4
    np.testing.assert_allclose(buf.advantages[last], 1.0 - 10.0, atol=1e-5)
    np.testing.assert_allclose(buf.advantages[buf.valid & ~last], 0.0, atol=1e-5)


def test_dqn_replay_keeps_the_bootstrap_after_truncation_only() -> None:
    for terminate_at, expected in ((None, 0.9), (5, 0.0)):
        agent = pl.deep.DQN(
            counting_vec_env(2, limit=5, terminate_at=terminate_at), n_envs=2,
            learning_starts=10_000,
            gamma=0.9, train_freq=1,
        )  # fmt: skip
        agent.learn(24)
        rb = agent.replay
        n = len(rb)
        assert n == 24  # the autoreset steps carry no transition
        ends = rb.next_obs[:n, 0] == 5.0  # the last state of an episode, not the reset state 0
        assert ends.sum() >= 4
        np.testing.assert_allclose(rb.discounts[:n][ends], expected)
        np.testing.assert_allclose(rb.discounts[:n][~ends], 0.9)
        np.testing.assert_array_equal(rb.next_obs[:n, 0], rb.obs[:n, 0] + 1)


def test_dqn_n_step_truncation_bootstraps_from_the_last_state() -> None:
    agent = pl.deep.DQN(
        counting_vec_env(1, limit=5),
        n_envs=1,
        learning_starts=10_000,
        gamma=0.5,
        n_step=3,
        train_freq=1,
    )
    agent.learn(5)
    rb = agent.replay
    n = len(rb)
    assert n == 5
    order = np.argsort(rb.obs[:n, 0])
    np.testing.assert_array_equal(rb.obs[order, 0], [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(rb.next_obs[order, 0], [3, 4, 5, 5, 5])
    np.testing.assert_allclose(rb.returns[order], [1.75, 1.75, 1.75, 1.5, 1.0])
    np.testing.assert_allclose(rb.discounts[order], [0.125, 0.125, 0.125, 0.25, 0.5])
