"""PPO: short runs on CartPole and Pendulum, seeding, API errors, and solving CartPole."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

import policylab as pl
from policylab.deep.ppo.losses import (
    clipped_surrogate_loss,
    clipped_surrogate_loss_grad,
    value_loss,
    value_loss_grad,
)
from policylab.deep.ppo.networks import ActorCritic
from policylab.exceptions import InvalidArgumentError


def test_short_run_discrete() -> None:
    agent = pl.deep.PPO("CartPole-v1", n_envs=4, n_steps=64, batch_size=64, n_epochs=2, seed=0)
    agent.learn(2048)
    assert agent.num_timesteps >= 2048 and agent.n_updates > 0 and agent.episodes > 0
    a = agent.predict(np.zeros(4, dtype=np.float32))
    assert a.shape == () and a in (0, 1)
    assert agent.predict(np.zeros((3, 4), dtype=np.float32)).shape == (3,)


def test_short_run_continuous_pendulum() -> None:
    agent = pl.deep.PPO(
        "Pendulum-v1", n_envs=2, n_steps=256, batch_size=128, n_epochs=2, gamma=0.9, seed=0
    )
    agent.learn(2048)
    assert agent.net.continuous and agent.episodes >= 8
    obs = np.random.default_rng(0).normal(size=(16, 3)).astype(np.float32)
    a = agent.predict(obs, deterministic=False)
    assert a.shape == (16, 1) and np.all(np.abs(a) <= 2.0)
    returns = pl.deep.evaluate(agent, episodes=2, seed=0)
    assert returns.shape == (2,) and np.all(returns < 0)


def test_same_seed_same_run_different_seed_different_run() -> None:
    def run(seed: int) -> tuple[list[torch.Tensor], list[float]]:
        agent = pl.deep.PPO("CartPole-v1", n_envs=2, n_steps=64, n_epochs=2, seed=seed)
        agent.learn(512)
        return agent.state_parameters(), list(agent.recent_returns)

    (p0, r0), (p1, r1), (p2, _) = run(7), run(7), run(8)
    for a, b in zip(p0, p1, strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert r0 == r1
    assert any(not torch.equal(a, b) for a, b in zip(p0, p2, strict=True))


def test_evaluate_counts_exact_episodes_and_is_seeded() -> None:
    agent = pl.deep.PPO("CartPole-v1", seed=0)
    a = pl.deep.evaluate(agent, episodes=7, seed=3, deterministic=False)
    b = pl.deep.evaluate(agent, episodes=7, seed=3, deterministic=False)
    assert a.shape == (7,)
    agent2 = pl.deep.PPO("CartPole-v1", seed=0)
    np.testing.assert_array_equal(
        pl.deep.evaluate(agent2, episodes=7, seed=3, deterministic=False), a
    )
    assert np.all(b > 0)


def test_callback_can_stop_training() -> None:
    seen = []

    def cb(agent: pl.deep.Agent, metrics: dict[str, float]) -> bool:
        seen.append(metrics)
        return False

    agent = pl.deep.PPO("CartPole-v1", n_steps=32)
    agent.learn(10_000, callback=cb)
    assert len(seen) == 1 and agent.num_timesteps < 100
    assert {"policy_loss", "value_loss", "entropy", "approx_kl", "learning_rate"} <= set(seen[0])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_steps": 0}, "n_steps"),
        ({"gamma": 2.0}, "gamma"),
        ({"bogus": 1}, "unknown PPOConfig field"),
        ({"n_epochs": "ten"}, "integer"),
        ({"activation": "sigmoid"}, "activation"),
    ],
)
def test_bad_config_is_refused_by_name(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InvalidArgumentError, match=match):
        pl.deep.PPO("CartPole-v1", **kwargs)


def test_bad_env_and_obs_are_refused() -> None:
    with pytest.raises(InvalidArgumentError, match="NoSuchEnv"):
        pl.deep.PPO("NoSuchEnv-v0")
    with pytest.raises(InvalidArgumentError, match="DQN needs a Discrete"):
        pl.deep.DQN("Pendulum-v1")
    agent = pl.deep.PPO("CartPole-v1")
    with pytest.raises(InvalidArgumentError, match="obs must have shape"):
        agent.predict(np.zeros(5))


def test_ppo_solves_cartpole() -> None:
    """The CartPole defaults (the zoo's) reach the 475 threshold over 100 greedy episodes."""
    fields, _ = pl.deep.default_config("ppo", "CartPole-v1")
    agent = pl.deep.PPO("CartPole-v1", seed=0, **fields)
    solved: list[float] = []

    def check(a: pl.deep.Agent, m: dict[str, float]) -> bool | None:
        if a.num_timesteps % 10_240 < a.config.n_steps * a.config.n_envs:
            r = pl.deep.evaluate(a, episodes=100, seed=1).mean()
            if r >= 475:
                solved.append(r)
                return False
        return None

    agent.learn(60_000, callback=check)
    assert solved, "PPO did not reach a mean return of 475 over 100 episodes in 60k steps"


def test_default_config_untuned_is_the_zoo_exactly() -> None:
    tuned, _ = pl.deep.default_config("ppo", "CartPole-v1")
    zoo, steps = pl.deep.default_config("ppo", "CartPole-v1", tuned=False)
    assert steps == 100_000
    assert (zoo["n_envs"], zoo["n_steps"], zoo["batch_size"], zoo["n_epochs"]) == (8, 32, 256, 20)
    assert "activation" not in zoo and tuned == zoo  # PPO keeps the zoo's settings
    dqn, _ = pl.deep.default_config("dqn", "Acrobot-v1", tuned=False)
    assert dqn["gradient_steps"] == dqn["train_freq"] == 4  # the zoo's -1: one per env step


@pytest.mark.parametrize(
    ("action_space", "act", "clip_vf"),
    [
        (gym.spaces.Discrete(3), "tanh", None),
        (gym.spaces.Discrete(2), "relu", 0.1),
        (gym.spaces.Box(-1.0, 1.0, (2,)), "elu", None),
        (gym.spaces.Box(-1.0, 1.0, (2,)), "tanh", 0.1),
    ],
)
def test_hand_written_update_gradient_equals_autograd(
    action_space: gym.Space[Any], act: str, clip_vf: float | None
) -> None:
    g = torch.Generator().manual_seed(0)
    net = ActorCritic(gym.spaces.Box(-1.0, 1.0, (5,)), action_space, (16, 8), act, 0.3, g)
    net = net.double()
    assert net.by_hand
    with torch.no_grad():  # away from the initialisation, so every term has a gradient
        for p in net.parameters():
            p.add_(0.3 * torch.randn(p.shape, generator=g, dtype=p.dtype))
    n = 64
    obs = torch.randn(n, 5, generator=g, dtype=torch.float64)
    actions = (
        torch.randint(0, int(action_space.n), (n,), generator=g)
        if isinstance(action_space, gym.spaces.Discrete)
        else torch.randn(n, 2, generator=g, dtype=torch.float64)
    )
    with torch.no_grad():
        old_logp = net.evaluate_actions(obs, actions)[0]
        old_logp += 0.3 * torch.randn(n, generator=g, dtype=torch.float64)
    old_v, adv, ret = torch.randn(3, n, generator=g, dtype=torch.float64)
    ent_coef, vf_coef = 0.01, 0.5
    logp, ent, v = net.evaluate_actions(obs, actions)
    ratio = (logp - old_logp).exp()
    loss = (
        clipped_surrogate_loss(ratio, adv, 0.2)
        + vf_coef * value_loss(v, old_v, ret, clip_vf)
        - ent_coef * ent.mean()
    )
    loss.backward()  # type: ignore[no-untyped-call]
    expected = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
    net.zero_grad(set_to_none=True)
    logp2, ent2, v2, cache = net.forward_cached(obs, actions)
    for a, b in ((logp2, logp), (ent2, ent), (v2, v)):
        torch.testing.assert_close(a, b.detach(), rtol=0, atol=1e-12)
    ratio2 = (logp2 - old_logp).exp()
    _, g_ratio = clipped_surrogate_loss_grad(ratio2, adv, 0.2)
    _, g_v = value_loss_grad(v2, old_v, ret, clip_vf)
    net.backward_cached(cache, g_ratio * ratio2, -ent_coef / n, vf_coef * g_v)
    for p, e in zip(net.parameters(), expected, strict=True):
        torch.testing.assert_close(p.grad, e, rtol=0, atol=1e-12)


def test_checkpoint_with_per_parameter_optimizer_state_still_loads(tmp_path: Path) -> None:
    # checkpoints written before the flat parameter buffer kept Adam's moments per layer
    agent = pl.deep.PPO("CartPole-v1", n_envs=2, n_steps=32, n_epochs=1, seed=0)
    agent.learn(64)
    flat = agent.optimizer.state_dict()
    buf = agent._flat
    assert buf is not None
    params = list(agent.net.parameters())
    sizes = [p.numel() for p in params]

    def own(p: torch.Tensor, key: str) -> torch.Tensor:  # p's view of a flat moment
        k = next(i for i, q in enumerate(buf.params) if q is p)
        return buf.view(flat["state"][0][key], k)

    split = [{k: own(p, k) for k in ("exp_avg", "exp_avg_sq")} for p in params]
    old = {
        "state": {i: {"step": flat["state"][0]["step"], **s} for i, s in enumerate(split)},
        "param_groups": [{**flat["param_groups"][0], "params": list(range(len(sizes)))}],
    }
    tensors = agent._state_tensors(training_state=True)
    tensors["optimizer"] = old
    other = pl.deep.PPO("CartPole-v1", n_envs=2, n_steps=32, n_epochs=1, seed=1)
    other._load_state_tensors(tensors)
    for key in ("exp_avg", "exp_avg_sq", "step"):
        torch.testing.assert_close(
            other.optimizer.state_dict()["state"][0][key], flat["state"][0][key]
        )
    for a, b in zip(other.state_parameters(), agent.state_parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    agent.save(tmp_path / "a.pt", training_state=True)
    back = pl.deep.PPO.load(tmp_path / "a.pt")
    assert back.optimizer.state_dict()["state"][0]["exp_avg"].shape == (sum(sizes),)


@pytest.mark.parametrize("action_space", [gym.spaces.Discrete(3), gym.spaces.Box(-1.0, 1.0, (2,))])
def test_numpy_sampling_draws_from_the_policy_with_its_log_probabilities(
    action_space: gym.Space[Any],
) -> None:
    g = torch.Generator().manual_seed(0)
    net = ActorCritic(gym.spaces.Box(-1.0, 1.0, (4,)), action_space, (16, 16), "tanh", -0.5, g)
    with torch.no_grad():  # a policy far from uniform
        net.policy_head.weight.mul_(300.0)
    obs = torch.randn(6, 4, generator=g)
    rng = np.random.default_rng(0)
    a, logp, v = net.sample_numpy(obs.numpy(), rng)
    with torch.no_grad():
        want_logp, _, want_v = net.evaluate_actions(obs, torch.as_tensor(a))
        mode = net.sample(obs, None, deterministic=True)[0]
    np.testing.assert_allclose(logp, want_logp.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(v, want_v.numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(
        net.sample_numpy(obs.numpy(), rng, deterministic=True)[0], mode.numpy(), atol=1e-6
    )
    # many draws at one state follow pi(. | s): frequencies or mean and std
    many = np.repeat(obs[:1].numpy(), 40_000, axis=0)
    draws = net.sample_numpy(many, rng)[0]
    if isinstance(action_space, gym.spaces.Discrete):
        with torch.no_grad():
            probs = torch.softmax(mlp_out(net, obs[:1]), -1)[0].numpy()
        freq = np.bincount(draws, minlength=3) / len(draws)
        np.testing.assert_allclose(freq, probs, atol=4 * np.sqrt(0.25 / len(draws)))
    else:
        std = float(np.exp(-0.5))
        np.testing.assert_allclose(draws.mean(0), mode[0].numpy(), atol=4 * std / 200)
        np.testing.assert_allclose(draws.std(0), [std, std], rtol=0.02)


def mlp_out(net: ActorCritic, obs: torch.Tensor) -> torch.Tensor:
    """The policy head's output o (logits or means) for a batch."""
    return net.policy_head(net.actor_torso(obs))


def test_whole_rollout_minibatch_gathered_once_equals_gathering_every_epoch() -> None:
    # a minibatch holding every stored step is gathered once and reused in each epoch;
    # gathering it afresh in each epoch's order gives the same update (up to rounding)
    class NoWhole(np.ndarray):
        def sum(self, *args: Any, **kwargs: Any) -> Any:  # never "every step"
            return np.int64(-1)

    def agent() -> pl.deep.PPO:
        a = pl.deep.PPO("CartPole-v1", n_envs=4, n_steps=32, batch_size=128, n_epochs=5, seed=2)
        a.learn(128)  # one rollout and one update
        a._collect()
        return a

    fast, slow = agent(), agent()
    slow.buffer.valid = slow.buffer.valid.view(NoWhole)
    fast._update()
    slow._update()
    for p, q in zip(fast.net.parameters(), slow.net.parameters(), strict=True):
        torch.testing.assert_close(p, q, rtol=1e-5, atol=1e-6)
    assert fast.rng.random() == slow.rng.random()  # the same draws


@pytest.mark.parametrize(
    "action_space", [gym.spaces.Discrete(3), gym.spaces.Box(-1.0, 1.0, (2,))], ids=str
)
def test_hand_written_gradient_on_the_agents_flat_blocks_equals_autograd(
    action_space: gym.Space[Any],
) -> None:
    # the layout the agent trains in: both MLPs' layers as [W^T; b] blocks of one flat
    # tensor, the log std beside them; the gradients land in the flat gradient
    import copy

    from policylab.deep.common.mlp_grad import FlatParameters

    g = torch.Generator().manual_seed(5)
    net = ActorCritic(gym.spaces.Box(-1.0, 1.0, (4,)), action_space, (8, 6), "tanh", 0.2, g)
    ref = copy.deepcopy(net)
    assert net.chains is not None
    flat = FlatParameters(list(net.parameters()), [*net.chains[0], *net.chains[1]])
    with torch.no_grad():  # away from the initialisation, so every term has a gradient
        flat.flat.add_(0.3 * torch.randn(flat.flat.shape, generator=g))
        ref.load_state_dict(net.state_dict())
    n = 32
    obs = torch.randn(n, 4, generator=g)
    actions = (
        torch.randint(0, 3, (n,), generator=g)
        if isinstance(action_space, gym.spaces.Discrete)
        else torch.randn(n, 2, generator=g)
    )
    adv, ret = torch.randn(2, n, generator=g)
    logp, ent, v = ref.evaluate_actions(obs, actions)
    ratio = logp.exp()  # old log-probabilities 0
    loss = clipped_surrogate_loss(ratio, adv, 0.2) + 0.5 * value_loss(v, v.detach(), ret, None)
    (loss - 0.01 * ent.mean()).backward()  # type: ignore[no-untyped-call]
    flat.flat.grad.fill_(7.0)  # type: ignore[union-attr]  # overwritten, not added to
    logp2, _, v2, cache = net.forward_cached(obs, actions)
    _, g_ratio = clipped_surrogate_loss_grad(logp2.exp(), adv, 0.2)
    _, g_v = value_loss_grad(v2, v2, ret, None)
    net.backward_cached(cache, g_ratio * logp2.exp(), -0.01 / n, 0.5 * g_v)
    for p, e in zip(net.parameters(), ref.parameters(), strict=True):
        torch.testing.assert_close(p.grad, e.grad, rtol=1e-5, atol=1e-6)
        # written into the flat gradient, not into tensors of their own
        assert p.grad.untyped_storage().data_ptr() == flat.flat.grad.data_ptr()  # type: ignore[union-attr]
