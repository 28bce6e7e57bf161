"""DQN: short runs with every option, targets against hand computation, seeding."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import policylab as pl
from policylab.deep.common.networks import clip_grad_norm
from policylab.deep.dqn.losses import q_learning_targets, td_loss, td_loss_grad
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
        "CartPole-v1", learning_starts=300, buffer_size=5000, target_update_interval=200,
        hidden=(32, 32), seed=0, **options,
    )  # fmt: skip
    agent.learn(1200)  # about 200 rounds of updates, 4 target updates
    assert agent.num_timesteps >= 1200 and agent.n_updates >= 180
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


@pytest.mark.parametrize(("double_q", "loss"), [(False, "huber"), (True, "mse")])
def test_hand_written_round_equals_autograd_steps(double_q: bool, loss: str) -> None:
    # one round of gradient steps by hand (minibatches drawn at once, one target pass)
    # against the same minibatches stepped one by one with autograd
    def agent() -> pl.deep.DQN:
        a = pl.deep.DQN(
            "CartPole-v1", hidden=(16, 16), learning_starts=10_000, gradient_steps=5,
            batch_size=8, double_q=double_q, loss=loss, learning_rate=1e-2, seed=3,
        )  # fmt: skip
        a.learn(300)  # fills the replay buffer, no update yet
        assert a.n_updates == 0 and a.q.chain is not None
        return a

    fast, slow = agent(), agent()
    stats = fast._train_steps_by_hand()
    losses, q_means = [], []
    b = slow.replay.sample(5 * 8)  # the same draws: the generators are in the same state
    for k in range(5):
        s = slice(8 * k, 8 * (k + 1))
        obs, next_obs = torch.as_tensor(b.obs[s]), torch.as_tensor(b.next_obs[s])
        with torch.no_grad():
            online = slow.q(next_obs) if double_q else None
            y = q_learning_targets(
                torch.as_tensor(b.returns[s]), torch.as_tensor(b.discounts[s]),
                slow.q_target(next_obs), online,
            )  # fmt: skip
        q = slow.q(obs).gather(1, torch.as_tensor(b.actions[s]).long().unsqueeze(1)).squeeze(1)
        slow._flat.flat.grad.zero_()  # type: ignore[union-attr]
        step_loss = td_loss(y - q, torch.ones(8), loss)
        step_loss.backward()  # type: ignore[no-untyped-call]
        losses.append(float(step_loss.detach()))
        q_means.append(float(q.detach().mean()))
        clip_grad_norm(slow._params, slow.config.max_grad_norm)
        slow.optimizer.step()
    for p, e in zip(fast.q.parameters(), slow.q.parameters(), strict=True):
        torch.testing.assert_close(p, e, rtol=1e-5, atol=1e-6)
    # the round's loss and mean Q: the means over its steps
    assert stats.tolist() == pytest.approx([np.mean(losses), np.mean(q_means)], rel=1e-5)
    assert not torch.equal(fast.q.head[0].weight, fast.q_target.head[0].weight)


def test_td_loss_grad_equals_autograd() -> None:
    td = torch.tensor([-3.0, -1.0, -0.4, 0.0, 0.7, 1.0, 2.5], dtype=torch.float64)
    w = torch.tensor([1.0, 0.5, 2.0, 1.0, 0.1, 1.0, 3.0], dtype=torch.float64)
    for kind in ("huber", "mse"):
        x = td.clone().requires_grad_()
        td_loss(x, w, kind).backward()  # type: ignore[no-untyped-call]
        loss, grad = td_loss_grad(td, w, kind)
        torch.testing.assert_close(loss, td_loss(td, w, kind))
        torch.testing.assert_close(grad, x.grad, rtol=0, atol=1e-15)


def test_prioritized_replay_still_learns_with_flat_parameters() -> None:
    agent = pl.deep.DQN("CartPole-v1", hidden=(16,), learning_starts=100, prioritized=True, seed=0)
    before = [p.detach().clone() for p in agent.q.parameters()]
    agent.learn(400)
    assert agent.n_updates > 0
    assert all(not torch.equal(p, b) for p, b in zip(agent.q.parameters(), before, strict=True))


def test_cached_target_values_follow_the_buffer_and_the_target_network() -> None:
    # a small buffer that wraps around, a target update every 50 steps: every cached
    # Q_target(S', .) must equal a fresh forward pass of the current target network
    agent = pl.deep.DQN(
        "CartPole-v1", hidden=(16,), learning_starts=50, buffer_size=300, batch_size=16,
        train_freq=8, gradient_steps=4, target_update_interval=50, seed=1,
    )  # fmt: skip
    idx = np.arange(300)
    for steps in (400, 430, 777):
        agent.learn(steps)
        cached = agent._next_target_q(idx)
        with torch.no_grad():
            fresh = agent.q_target(torch.as_tensor(agent.replay.next_obs))
        torch.testing.assert_close(cached, fresh, rtol=1e-6, atol=1e-6)
        assert agent._target_q_fresh.all()


def test_acting_without_forward_pass_draws_as_before() -> None:
    # epsilon 1: every action is random and the generator is consumed as with a forward
    agent = pl.deep.DQN("CartPole-v1", hidden=(8,), seed=2)
    rng = np.random.default_rng(7)
    agent.rng = np.random.default_rng(7)
    obs = torch.zeros(5, 4)
    got = agent._act(obs, deterministic=False)
    explore = rng.random(5) < 1.0
    assert explore.all()
    np.testing.assert_array_equal(got, rng.integers(0, 2, 5))
    assert agent.rng.random() == rng.random()


def test_numpy_greedy_actions_equal_the_network_argmax() -> None:
    agent = pl.deep.DQN("CartPole-v1", hidden=(64, 64), seed=4)
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(64, 4)).astype(np.float32))
    with torch.no_grad():
        q = agent.q(obs)
    gap = q.sort(1).values.diff(dim=1).abs().min()
    assert gap > 1e-4  # no near-ties, where rounding could pick the other action
    np.testing.assert_array_equal(agent._greedy(obs), q.argmax(1).numpy())
    np.testing.assert_array_equal(agent.predict(obs.numpy()), q.argmax(1).numpy())


def test_training_flushes_subnormal_numbers_and_restores_the_mode() -> None:
    tiny = torch.tensor([1e-39])
    seen: list[float] = []

    def probe(a: pl.deep.Agent, _: dict[str, float]) -> bool:
        seen.append(float(tiny * 1.0))
        return False

    pl.deep.DQN("CartPole-v1", hidden=(8,), learning_starts=10).learn(100, callback=probe)
    assert seen == [0.0]  # inside learn: flushed to zero
    assert float(tiny * 1.0) > 0.0  # after: subnormals again
