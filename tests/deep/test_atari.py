"""Atari from pixels: Nature-CNN DQN and PPO on ALE/Pong-v5 for a few thousand frames."""

from __future__ import annotations

import numpy as np

import policylab as pl


def test_pong_pixels_dqn_and_ppo() -> None:
    dqn = pl.deep.DQN(
        "ALE/Pong-v5", buffer_size=2000, learning_starts=1800, train_freq=50, batch_size=16, seed=0
    )
    assert dqn.observation_space.shape == (4, 84, 84) and dqn.observation_space.dtype == np.uint8
    assert isinstance(dqn.q.torso, pl.deep.NatureCNN)
    dqn.learn(2000)
    assert dqn.n_updates >= 3 and dqn.replay.obs.dtype == np.uint8
    ppo = pl.deep.PPO("ALE/Pong-v5", n_envs=2, n_steps=128, batch_size=256, n_epochs=1, seed=0)
    assert ppo.net.shared
    ppo.learn(1024)
    assert ppo.n_updates == 4
    a = ppo.predict(np.zeros((4, 84, 84), dtype=np.uint8))
    assert 0 <= int(a) < 6
