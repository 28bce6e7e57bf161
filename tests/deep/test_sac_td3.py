"""SAC and TD3: every loss and target against hand computation, networks, runs, bad input."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import pytest
import torch

import policylab as pl
from policylab.deep.common.losses import clipped_double_q_targets, polyak_update, twin_q_loss
from policylab.deep.common.networks import TwinQNetwork
from policylab.deep.sac.losses import (
    entropy_coef_loss,
    sac_actor_loss,
    squashed_gaussian_log_prob,
)
from policylab.deep.td3.losses import smoothed_target_actions, td3_actor_loss
from policylab.exceptions import InvalidArgumentError, NonFiniteError

TINY: dict[str, Any] = dict(hidden=(16, 16), batch_size=32, learning_starts=200)
ALGOS = ["sac", "td3"]


# ------------------------------------------------------------------ equations
def test_clipped_double_q_targets_hand_computed() -> None:
    r = torch.tensor([1.0, 2.0])
    d = torch.tensor([0.99, 0.0])
    next_q = torch.tensor([[3.0, 5.0], [4.0, 1.0]])  # min over critics: [3, 1]
    td3 = clipped_double_q_targets(r, d, next_q)
    torch.testing.assert_close(td3, torch.tensor([1 + 0.99 * 3, 2.0]))
    sac = clipped_double_q_targets(r, d, next_q, torch.tensor([-1.0, 2.0]), 0.5)
    torch.testing.assert_close(sac, torch.tensor([1 + 0.99 * (3 + 0.5), 2.0]))


def test_twin_q_loss_hand_computed() -> None:
    q = torch.tensor([[1.0, 2.0], [3.0, 0.0]])
    y = torch.tensor([2.0, 2.0])
    # critic 1 errors (-1, 0): mean square 0.5; critic 2 errors (1, -2): 2.5
    torch.testing.assert_close(twin_q_loss(q, y), torch.tensor(0.5 * (0.5 + 2.5)))


def test_polyak_update_hand_computed() -> None:
    target = [torch.tensor([0.0, 10.0]), torch.tensor([[2.0]])]
    online = [torch.tensor([1.0, 0.0]), torch.tensor([[4.0]])]
    polyak_update(target, online, 0.1)
    torch.testing.assert_close(target[0], torch.tensor([0.1, 9.0]))
    torch.testing.assert_close(target[1], torch.tensor([[2.2]]))


def test_squashed_gaussian_log_prob_hand_computed() -> None:
    # u = 0, N(0, 1): log N = -log(2 pi) / 2 and the tanh Jacobian is 1
    zero = torch.zeros(1, 1)
    torch.testing.assert_close(
        squashed_gaussian_log_prob(zero, zero, zero), torch.tensor([-0.5 * math.log(2 * math.pi)])
    )
    # u = 1 under N(0.5, 2^2): z = 0.25
    u, mean, log_std = torch.tensor([[1.0]]), torch.tensor([[0.5]]), torch.tensor([[math.log(2)]])
    expected = (
        -0.5 * 0.25**2 - math.log(2) - 0.5 * math.log(2 * math.pi) - math.log(1 - math.tanh(1) ** 2)
    )
    torch.testing.assert_close(
        squashed_gaussian_log_prob(u, mean, log_std), torch.tensor([expected])
    )
    # two dimensions add; a large |u| stays finite (log(1 - tanh^2) ~ 2 log 2 - 2|u|)
    u2 = torch.tensor([[1.0, 30.0]])
    m2, s2 = torch.tensor([[0.5, 30.0]]), torch.tensor([[math.log(2), 0.0]])
    big = -0.5 * math.log(2 * math.pi) - (2 * math.log(2) - 60.0)
    torch.testing.assert_close(
        squashed_gaussian_log_prob(u2, m2, s2), torch.tensor([expected + big]), rtol=1e-5, atol=1e-4
    )


def test_sac_actor_loss_hand_computed() -> None:
    log_prob = torch.tensor([-1.0, 0.5])
    q = torch.tensor([[1.0, 4.0], [2.0, 3.0]])  # min: [1, 3]
    expected = ((0.2 * -1.0 - 1.0) + (0.2 * 0.5 - 3.0)) / 2
    torch.testing.assert_close(sac_actor_loss(log_prob, q, 0.2), torch.tensor(expected))


def test_entropy_coef_loss_value_and_direction() -> None:
    log_alpha = torch.tensor(math.log(0.5), requires_grad=True)
    log_prob = torch.tensor([-1.0, -3.0])  # entropy estimate 2 > target -2: alpha must fall
    loss = entropy_coef_loss(log_alpha, log_prob, -2.0)
    torch.testing.assert_close(loss.detach(), torch.tensor(4 * math.log(0.5)))
    loss.backward()
    assert log_alpha.grad is not None and float(log_alpha.grad) == pytest.approx(4.0)


def test_smoothed_target_actions_and_td3_actor_loss() -> None:
    a = smoothed_target_actions(torch.tensor([[0.9, -0.2]]), torch.tensor([[0.7, -0.1]]), 0.5)
    torch.testing.assert_close(a, torch.tensor([[1.0, -0.3]]))
    torch.testing.assert_close(td3_actor_loss(torch.tensor([1.0, 3.0])), torch.tensor(-2.0))


def test_twin_q_network_is_two_mlps_and_detached_params_give_no_critic_grads() -> None:
    net = TwinQNetwork(3, 2, (8, 5), "relu", torch.Generator().manual_seed(0))
    obs, act = torch.randn(4, 3), torch.randn(4, 2, requires_grad=True)
    q = net(obs, act)
    assert q.shape == (2, 4)
    ws, bs = list(net.weights), list(net.biases)  # the first layer: W_s and W_a
    assert [tuple(w.shape) for w in ws] == [(2, 3, 8), (2, 2, 8), (2, 8, 5), (2, 5, 1)]
    for k in range(2):
        h = torch.relu(obs @ ws[0][k] + act @ ws[1][k] + bs[0][k])
        h = torch.relu(h @ ws[2][k] + bs[1][k])
        torch.testing.assert_close(q[k], (h @ ws[3][k] + bs[2][k]).squeeze(-1))
    q_detached = net(obs, act, [p.detach() for p in net.parameters()])
    torch.testing.assert_close(q_detached, q)
    torch.testing.assert_close(net(obs, act, [p.detach()[:1] for p in net.parameters()]), q[:1])
    q_detached.sum().backward()
    assert act.grad is not None and all(p.grad is None for p in net.parameters())


def test_twin_q_network_gradients_are_those_of_two_mlps() -> None:
    net = TwinQNetwork(3, 2, (8, 5), "relu", torch.Generator().manual_seed(1))
    with torch.no_grad():  # nonzero biases, so that their gradients are tested too
        for b in net.biases:
            b.normal_(generator=torch.Generator().manual_seed(2))
    obs = torch.randn(6, 3, generator=torch.Generator().manual_seed(3))
    act = torch.randn(6, 2, generator=torch.Generator().manual_seed(4)).requires_grad_()
    y = torch.randn(6, generator=torch.Generator().manual_seed(5))
    ((net(obs, act) - y) ** 2).sum().backward()
    got = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
    got_act = act.grad.clone()  # type: ignore[union-attr]
    ps = [p.detach().clone().requires_grad_() for p in net.parameters()]
    act.grad = None
    loss = torch.zeros(())
    for k in range(2):  # the two critics as plain MLPs on [s, a]
        h = torch.relu(obs @ ps[0][k] + act @ ps[1][k] + ps[4][k])
        h = torch.relu(h @ ps[2][k] + ps[5][k])
        loss = loss + (((h @ ps[3][k] + ps[6][k]).squeeze(-1) - y) ** 2).sum()
    loss.backward()
    for g, p in zip(got, ps, strict=True):
        torch.testing.assert_close(g, p.grad)
    torch.testing.assert_close(got_act, act.grad)


def test_actions_are_rescaled_to_the_box_bounds() -> None:
    agent = pl.deep.TD3(_BoxEnv(low=[-2.0, 0.0], high=[2.0, 1.0]), **TINY)
    np.testing.assert_allclose(
        agent.to_env_actions(np.array([[-1.0, 1.0], [0.0, 0.0]])), [[-2.0, 1.0], [0.0, 0.5]]
    )
    actions = agent.predict(np.zeros((50, 2), dtype=np.float32) + np.arange(50)[:, None] / 10)
    assert np.all(actions >= [-2.0, 0.0]) and np.all(actions <= [2.0, 1.0])
    sac = pl.deep.SAC(_BoxEnv(low=[-2.0, 0.0], high=[2.0, 1.0]), **TINY)
    assert sac.target_entropy == -2.0 and sac.alpha == pytest.approx(1.0)
    assert pl.deep.SAC("Pendulum-v1", ent_coef="auto_0.1", **TINY).alpha == pytest.approx(0.1)


# ------------------------------------------------------------------- runs
@pytest.mark.parametrize("algo", ALGOS)
def test_short_run_pendulum_counts_updates_like_sb3(algo: str) -> None:
    agent = pl.deep.ALGORITHMS[algo]("Pendulum-v1", seed=0, **TINY)
    agent.learn(600)
    # updates start once more than learning_starts steps are taken: one per step after
    assert agent.num_timesteps == 600 and agent.n_updates == 400
    assert len(agent.replay) == 600
    a = agent.predict(np.zeros(3, dtype=np.float32))
    assert a.shape == (1,) and -2.0 <= float(a[0]) <= 2.0


@pytest.mark.parametrize("algo", ALGOS)
def test_same_seed_same_run(algo: str) -> None:
    def run() -> list[torch.Tensor]:
        agent = pl.deep.ALGORITHMS[algo]("Pendulum-v1", seed=7, n_envs=2, **TINY)
        agent.learn(400)
        return [p.detach().clone() for p in agent.state_parameters()]

    for p, q in zip(run(), run(), strict=True):
        torch.testing.assert_close(p, q, rtol=0, atol=0)


@pytest.mark.parametrize("algo", ALGOS)
def test_save_load_gives_identical_actions(tmp_path: Path, algo: str) -> None:
    cls = pl.deep.ALGORITHMS[algo]
    agent = cls("Pendulum-v1", seed=3, normalize_obs=True, **TINY)
    agent.learn(300)
    agent.save(tmp_path / "a.pt")
    loaded = cls.load(tmp_path / "a.pt")
    obs = np.random.default_rng(0).normal(size=(20, 3)).astype(np.float32)
    np.testing.assert_array_equal(agent.predict(obs), loaded.predict(obs))
    assert loaded.config == agent.config and pl.deep.load(tmp_path / "a.pt").algo == algo


@pytest.mark.parametrize("algo", ALGOS)
def test_resume_continues_step_count_and_replay_buffer(tmp_path: Path, algo: str) -> None:
    cls = pl.deep.ALGORITHMS[algo]
    run = tmp_path / "run"
    agent = cls("Pendulum-v1", seed=0, checkpoint_every=200, **TINY)
    agent.learn(500, run_dir=run)
    resumed = cls.resume(run)
    assert resumed.num_timesteps == 500 and resumed.n_updates == agent.n_updates == 300
    assert len(resumed.replay) == len(agent.replay) == 500
    for name in ("obs", "actions", "returns", "next_obs", "discounts"):
        np.testing.assert_array_equal(getattr(resumed.replay, name), getattr(agent.replay, name))
    assert resumed.replay.pos == agent.replay.pos
    header = (run / "progress.csv").read_text().splitlines()[0].split(",")
    assert set(agent.metric_names) <= set(header)  # logged from the first row on
    obs = np.random.default_rng(0).normal(size=(8, 3)).astype(np.float32)
    np.testing.assert_array_equal(resumed.predict(obs), agent.predict(obs))
    resumed.learn(700, run_dir=run)
    assert resumed.num_timesteps == 700 and len(resumed.replay) == 700
    assert resumed.n_updates == 500


WALKERS = ["HalfCheetah-v5", "Hopper-v5", "Walker2d-v5", "Ant-v5", "Humanoid-v5"]


@pytest.mark.parametrize("env_id", WALKERS)
@pytest.mark.parametrize("algo", ALGOS)
def test_short_run_on_each_walker(algo: str, env_id: str) -> None:
    agent = pl.deep.ALGORITHMS[algo](
        env_id, seed=0, hidden=(16,), batch_size=16, learning_starts=100
    )
    agent.learn(250)
    assert agent.num_timesteps == 250 and agent.n_updates == 150
    space = agent.action_space
    a = agent.predict(agent.envs.single_observation_space.sample())
    assert a.shape == space.shape and np.all(a >= space.low) and np.all(a <= space.high)


# -------------------------------------------------------------- bad input
class _BoxEnv(gym.Env[np.ndarray, np.ndarray]):
    """A 2-d observation; reward -|a|^2; NaN observation or reward from ``nan_at`` on."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(
        self,
        low: Any = -1.0,
        high: Any = 1.0,
        nan_at: int | None = None,
        nan_in: str = "obs",
    ) -> None:
        self.observation_space = gym.spaces.Box(-10.0, 10.0, (2,), np.float32)
        self.action_space = gym.spaces.Box(
            np.broadcast_to(np.asarray(low, np.float32), (2,)),
            np.broadcast_to(np.asarray(high, np.float32), (2,)),
            dtype=np.float32,
        )
        self.nan_at, self.nan_in, self.t = nan_at, nan_in, 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        return np.zeros(2, np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.t += 1
        obs = np.full(2, 0.1 * (self.t % 7), np.float32)
        reward = -float(np.sum(np.square(action)))
        if self.nan_at is not None and self.t >= self.nan_at:
            if self.nan_in == "obs":
                obs[1] = np.nan
            else:
                reward = math.nan
        return obs, reward, False, self.t % 50 == 0, {}


@pytest.mark.parametrize("algo", ALGOS)
def test_discrete_and_unbounded_action_spaces_are_refused(algo: str) -> None:
    cls = pl.deep.ALGORITHMS[algo]
    with pytest.raises(InvalidArgumentError, match="continuous action space"):
        cls("CartPole-v1")
    with pytest.raises(InvalidArgumentError, match="finite"):
        cls(_BoxEnv(low=-np.inf, high=np.inf))


def test_bad_config_values_are_refused() -> None:
    for bad in ({"ent_coef": "often"}, {"ent_coef": -1.0}, {"ent_coef": "auto_-2"}, {"tau": 0.0}):
        with pytest.raises(InvalidArgumentError):
            pl.deep.SAC("Pendulum-v1", **bad)
    with pytest.raises(InvalidArgumentError, match="policy_delay"):
        pl.deep.TD3("Pendulum-v1", policy_delay=0)


@pytest.mark.parametrize("nan_in", ["obs", "reward"])
def test_nan_from_the_env_stops_with_the_step_and_keeps_the_checkpoint(
    tmp_path: Path, nan_in: str
) -> None:
    agent = pl.deep.SAC(_BoxEnv(nan_at=260, nan_in=nan_in), checkpoint_every=100, **TINY)
    run = tmp_path / "run"
    what = "observation" if nan_in == "obs" else "reward"
    with pytest.raises(NonFiniteError, match=f"non-finite {what} at env step 260"):
        agent.learn(1000, run_dir=run)
    kept = pl.deep.SAC.load(run / "checkpoint.pt")
    assert kept.num_timesteps == 200
    assert all(torch.isfinite(p).all() for p in kept.state_parameters())


@pytest.mark.parametrize("algo", ALGOS)
def test_nan_loss_stops_with_its_name_and_step(tmp_path: Path, algo: str) -> None:
    agent = pl.deep.ALGORITHMS[algo](_BoxEnv(), checkpoint_every=100, **TINY)
    run = tmp_path / "run"
    agent.learn(300, run_dir=run)
    with torch.no_grad():
        agent.critic.weights[0].fill_(math.nan)
    with pytest.raises(NonFiniteError, match=r"critic_loss.*after env step 301"):
        agent.learn(1000, run_dir=run)
    assert pl.deep.ALGORITHMS[algo].load(run / "checkpoint.pt").num_timesteps == 300
