"""DQN: short runs with every option, targets against hand computation, seeding."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import policylab as pl
from policylab.deep.dqn.losses import q_learning_targets
from policylab.deep.dqn.networks import QNetwork


@pytest.mark.parametrize(
    "options",
    [
        {},
        {"double_q": False, "dueling": True},
        {"n_step": 3, "prioritized": True},
        {"n_envs": 4, "tau": 0.05, "loss": "mse", "normalize_obs": True},
    ],
)
def test_short_run_cartpole(options: dict[str, object]) -> None:
    agent = pl.deep.DQN(
        "CartPole-v1", learning_starts=500, buffer_size=5000, target_update_interval=200,
        hidden=(32, 32), seed=0, **options,
    )  # fmt: skip
    agent.learn(2000)
    assert agent.num_timesteps >= 2000 and agent.n_updates > 0
    assert agent.epsilon < 1.0
    assert agent.predict(np.zeros(4, dtype=np.float32)) in (0, 1)


def test_q_learning_targets_hand_computed() -> None:
    returns = torch.tensor([1.0, 2.0, 3.0])
    discounts = torch.tensor([0.9, 0.0, 0.81])
    q_target = torch.tensor([[1.0, 5.0], [7.0, 8.0], [4.0, 2.0]])
    q_online = torch.tensor([[3.0, 0.0], [0.0, 1.0], [0.0, 1.0]])
    dqn = q_learning_targets(returns, discounts, q_target, None)
    torch.testing.assert_close(dqn, torch.tensor([1 + 0.9 * 5, 2.0, 3 + 0.81 * 4]))
    double = q_learning_targets(returns, discounts, q_target, q_online)
    torch.testing.assert_close(double, torch.tensor([1 + 0.9 * 1, 2.0, 3 + 0.81 * 2]))


def test_dueling_head_is_value_plus_centred_advantage() -> None:
    import gymnasium as gym

    net = QNetwork(gym.spaces.Box(-1, 1, (3,)), gym.spaces.Discrete(4), (8,), "relu", dueling=True)
    x = torch.randn(5, 3)
    h = net.torso(x)
    adv = net.advantage(h)
    torch.testing.assert_close(net(x), net.value(h) + adv - adv.mean(1, keepdim=True))
    torch.testing.assert_close(net(x).mean(1), net.value(h).squeeze(1))


def test_same_seed_same_run() -> None:
    def run() -> list[torch.Tensor]:
        agent = pl.deep.DQN(
            "CartPole-v1", learning_starts=200, hidden=(16,), seed=5, prioritized=True
        )
        agent.learn(800)
        return agent.state_parameters()

    for a, b in zip(run(), run(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)


def test_epsilon_decays_linearly() -> None:
    agent = pl.deep.DQN("CartPole-v1", exploration_fraction=0.5, exploration_final_eps=0.1)
    agent.target_steps = 1000
    agent.num_timesteps = 250
    assert agent.epsilon == pytest.approx(1.0 - 0.5 * 0.9)
    agent.num_timesteps = 900
    assert agent.epsilon == pytest.approx(0.1)
