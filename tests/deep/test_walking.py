"""The walking reward of Heess et al. (2017) on hand-set MuJoCo states."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import policylab as pl
from policylab.exceptions import InvalidArgumentError


def _walker(env_id: str, v_max: float = 2.0) -> pl.deep.WalkingReward:
    env = pl.deep.WalkingReward(gym.make(env_id), v_max=v_max)
    env.reset(seed=0)
    return env


def _set(env: pl.deep.WalkingReward, qpos: dict[int, float], qvel: dict[int, float]) -> None:
    u = env.unwrapped
    pos, vel = u.init_qpos.copy(), np.zeros(u.model.nv)
    for i, v in qpos.items():
        pos[i] = v
    for i, v in qvel.items():
        vel[i] = v
    u.set_state(pos, vel)


def test_equation_hand_computed() -> None:
    u = np.array([1.0, -2.0])  # ||u||^2 = 5
    r = pl.deep.walking_reward(1.5, 0.2, -0.4, 0.3, u, v_max=3.0)
    assert r == pytest.approx(1.5 - 0.005 * (0.04 + 0.16) - 0.05 * 0.09 - 0.02 * 5 + 0.02)
    assert pl.deep.walking_reward(5.0, 0, 0, 0, np.zeros(2), v_max=3.0) == pytest.approx(3.02)


@pytest.mark.parametrize("env_id", ["HalfCheetah-v5", "Hopper-v5", "Walker2d-v5"])
def test_planar_walkers_read_rootx_rootz(env_id: str) -> None:
    env = _walker(env_id, v_max=2.0)
    n = env.action_space.shape[0]
    _set(env, {}, {})
    assert env.reward_now(np.zeros(n)) == pytest.approx(0.02)  # standing still: the bonus only
    _set(env, {}, {0: 1.25})
    assert env.root_state() == pytest.approx((1.25, 0.0, 0.0, 0.0))
    assert env.reward_now(np.zeros(n)) == pytest.approx(1.25 + 0.02)
    _set(env, {}, {0: 3.0, 1: 0.5})  # v_x above the cap; v_z = 0.5
    assert env.root_state() == pytest.approx((3.0, 0.0, 0.5, 0.0))
    assert env.reward_now(np.zeros(n)) == pytest.approx(2.0 - 0.005 * 0.25 + 0.02)
    _set(env, {}, {0: -1.0})  # walking backwards is penalised, not clipped
    u = np.full(n, 0.5)
    assert env.reward_now(u) == pytest.approx(-1.0 - 0.02 * 0.25 * n + 0.02)
    assert env.reward_now(np.full(n, 7.0)) == pytest.approx(-1.0 - 0.02 * n + 0.02)  # clipped u


@pytest.mark.parametrize("env_id", ["Ant-v5", "Humanoid-v5"])
def test_free_walkers_read_the_root_free_joint(env_id: str) -> None:
    env = _walker(env_id, v_max=2.0)
    n = env.action_space.shape[0]
    _set(env, {1: 0.4}, {0: 2.5, 1: 0.3, 2: -0.2})
    assert env.root_state() == pytest.approx((2.5, 0.3, -0.2, 0.4))
    expected = 2.0 - 0.005 * (0.09 + 0.04) - 0.05 * 0.16 + 0.02
    assert env.reward_now(np.zeros(n)) == pytest.approx(expected)
    _set(env, {1: -1.0}, {})
    assert env.reward_now(np.zeros(n)) == pytest.approx(-0.05 + 0.02)


def test_step_reward_and_env_reward_in_info() -> None:
    env = _walker("Walker2d-v5", v_max=3.0)
    plain = gym.make("Walker2d-v5")
    plain.reset(seed=0)
    a = np.full(6, 0.3, dtype=np.float32)
    _, r, _, _, info = env.step(a)
    _, r_env, _, _, _ = plain.step(a)
    assert info["env_reward"] == pytest.approx(float(r_env))
    assert r == pytest.approx(env.reward_now(a)) and r != pytest.approx(float(r_env))


def test_unknown_env_and_bad_v_max_are_refused() -> None:
    with pytest.raises(InvalidArgumentError, match="does not know how to read"):
        pl.deep.WalkingReward(gym.make("Pendulum-v1"))
    with pytest.raises(InvalidArgumentError, match="does not know how to read"):
        pl.deep.WalkingReward(gym.make("Swimmer-v5"))
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InvalidArgumentError, match="v_max"):
            pl.deep.WalkingReward(gym.make("Hopper-v5"), v_max=bad)


def test_agent_on_the_walking_reward_records_it_in_run_json(tmp_path: Path) -> None:
    venv = pl.deep.walking_vec_env("Hopper-v5", 1, v_max=1.5)
    agent = pl.deep.SAC(venv, hidden=(16,), batch_size=16, learning_starts=50)
    assert agent.env_id == "Hopper-v5"
    agent.learn(120, run_dir=tmp_path / "run")
    doc = json.loads((tmp_path / "run" / "run.json").read_text())
    assert doc["reward"] == {"name": "walking", "v_max": 1.5}
    resumed = pl.deep.SAC.resume(tmp_path / "run")  # continues on the walking reward
    assert pl.deep.common.walking.reward_description(resumed.envs)["v_max"] == 1.5
    resumed.learn(150, run_dir=tmp_path / "run")
    doc = json.loads((tmp_path / "run" / "run.json").read_text())
    assert doc["reward"] == {"name": "walking", "v_max": 1.5}
