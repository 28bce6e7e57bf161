"""MDPEnv and rollout: check_env on every registered env, seeding, truncation, episodes."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import policylab as pl
from policylab.exceptions import InvalidActionError


@pytest.mark.parametrize("env_id", pl.register_envs())
def test_check_env_on_every_registered_env(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert info["action_mask"].dtype == np.int8


def test_terminated_on_terminal_state_and_masks():
    mdp = pl.problems.mountain_gridworld()
    env = pl.MDPEnv(mdp)
    obs, info = env.reset(seed=0)
    assert mdp.states[obs] == (2, 0)
    obs, r, term, trunc, _ = env.step(mdp.action_index("right"))
    assert (mdp.states[obs], r, term, trunc) == ((2, 1), -1.0, False, False)
    obs, r, term, trunc, _ = env.step(mdp.action_index("right"))
    assert (mdp.states[obs], r, term, trunc) == ((2, 2), 5.0, True, False)
    with pytest.raises(InvalidActionError, match="terminated"):
        env.step(0)


def test_truncated_by_step_limit_on_continuing_task():
    env = gym.make("policylab/RecyclingRobot-v0")
    env.reset(seed=0)
    n, trunc, term = 0, False, False
    while not (term or trunc):
        _, _, term, trunc, _ = env.step(1)  # wait forever
        n += 1
    assert trunc and not term and n == 1000
    env = pl.MDPEnv(pl.problems.recycling_robot(), max_steps=5)
    env.reset(seed=0)
    flags = [env.step(1)[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]


def test_invalid_action_policy():
    mdp = pl.problems.recycling_robot()
    strict = pl.MDPEnv(mdp, invalid_action="raise")
    strict.reset(seed=0)
    with pytest.raises(InvalidActionError, match="'recharge' is not available in state 'high'"):
        strict.step(2)
    lenient = pl.MDPEnv(mdp, invalid_action="stay", invalid_reward=-1.0)
    obs, _ = lenient.reset(seed=0)
    obs2, r, *_ = lenient.step(2)
    assert obs2 == obs and r == -1.0


def test_env_seeding_reproducible():
    def run(seed):
        env = gym.make("policylab/SlipperyGridworld-v0")
        obs, _ = env.reset(seed=seed)
        out = [int(obs)]
        for a in [0, 1, 2, 3] * 5:
            obs, r, term, trunc, _ = env.step(a)
            out.append((int(obs), r))
            if term:
                break
        return out

    assert run(3) == run(3)


def test_reset_with_start_option():
    mdp = pl.problems.slippery_gridworld()
    env = pl.MDPEnv(mdp)
    obs, info = env.reset(seed=0, options={"state": 3})
    assert info["state"] == 3 and mdp.states[obs] == 3
    with pytest.raises(pl.InvalidArgumentError, match="terminal"):
        env.reset(options={"state": 4})


def test_ansi_render():
    env = pl.MDPEnv(pl.problems.mountain_gridworld(), render_mode="ansi")
    env.reset(seed=0)
    assert env.render() == ".M.\n.MM\nA.G\n"


def test_mdp_env_bad_input_is_a_policylab_error():
    from policylab.envs import MDPEnv
    from policylab.exceptions import InvalidActionError, InvalidArgumentError

    robot = pl.problems.recycling_robot()
    with pytest.raises(InvalidArgumentError, match="MDPEnv wraps a FiniteMDP"):
        MDPEnv("recycling-robot")
    with pytest.raises(InvalidArgumentError, match="max_steps"):
        MDPEnv(robot, max_steps=1.5)
    env = MDPEnv(robot)
    with pytest.raises(InvalidArgumentError, match="seed must be a non-negative integer"):
        env.reset(seed=-1)
    env.reset(seed=0)
    for bad in ("search", 1.5, True):
        with pytest.raises(InvalidActionError, match=r"index in Discrete\(3\)"):
            env.step(bad)
    env.step(np.array(0))  # a 0-d array (what spaces sample) is an index


def test_policy_and_problem_lookup_bad_input():
    from policylab.exceptions import InvalidArgumentError, InvalidPolicyError
    from policylab.problems.registry import get_problem

    with pytest.raises(InvalidPolicyError, match="built for a FiniteMDP"):
        pl.Policy.uniform("recycling-robot")
    with pytest.raises(InvalidArgumentError, match="takes no parameter 'bogus'"):
        get_problem("recycling-robot", bogus=1)
    with pytest.raises(InvalidArgumentError, match="runs in a FiniteMDP or a Gymnasium env"):
        pl.rollout("robot", pl.Policy.uniform(pl.problems.recycling_robot()))
    with pytest.raises(pl.exceptions.InvalidMDPError, match="cannot make Gymnasium env"):
        pl.FiniteMDP.from_gymnasium("NoSuchEnv-v0")
