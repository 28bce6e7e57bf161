"""PettingZoo AEC environments (PettingZoo's api_test) and the Gymnasium env with action_mask."""

from __future__ import annotations

import numpy as np
import pytest

from policylab.exceptions import InvalidActionError, InvalidArgumentError
from policylab.games import CONNECT_FOUR, TIC_TAC_TOE
from policylab.games.gym_env import GameEnv


@pytest.mark.parametrize("game", ["tic-tac-toe", "connect-four"])
def test_pettingzoo_api_test(game):
    from pettingzoo.test import api_test

    from policylab.games.pettingzoo_env import env

    api_test(env(game), num_cycles=200, verbose_progress=False)


def test_aec_rewards_and_illegal_move():
    from policylab.games.pettingzoo_env import env

    e = env("tic-tac-toe")
    e.reset()
    for a in (0, 3, 1, 4, 2):  # X wins on the top row
        obs, *_ = e.last()
        assert obs["action_mask"][a] == 1
        e.step(a)
    assert e.rewards == {"player_0": 1.0, "player_1": -1.0}
    assert all(e.terminations.values())
    e.reset()
    e.step(4)
    with pytest.raises(InvalidActionError, match="player_1 played 4"):
        e.step(4)
    obs = e.observe("player_1")["observation"]
    assert obs.shape == (3, 3, 2) and obs[1, 1, 1] == 1 and obs[1, 1, 0] == 0  # X is the other


def test_gym_env_against_perfect_draws_and_checks():
    from gymnasium.utils.env_checker import check_env

    check_env(GameEnv("connect-four", "random"), skip_render_check=True)
    env = GameEnv("tic-tac-toe", "perfect", play_as=1)
    rng = np.random.default_rng(0)
    for ep in range(10):
        obs, _ = env.reset(seed=ep)
        assert obs["action_mask"].sum() == 8  # perfect moved first
        done = False
        while not done:
            legal = np.flatnonzero(obs["action_mask"])
            obs, r, done, trunc, _ = env.step(int(rng.choice(legal)))
            assert not trunc
        assert r in (-1.0, 0.0)  # a random mover never beats perfect play
    with pytest.raises(InvalidActionError, match="step\\(\\) after the end"):
        env.step(0)
    env.reset(seed=0)
    taken = int(np.flatnonzero(env.state.action_mask() == 0)[0])
    with pytest.raises(InvalidActionError, match="action_mask"):
        env.step(taken)
    with pytest.raises(InvalidArgumentError, match="play_as"):
        GameEnv("tic-tac-toe", play_as=2)
    assert CONNECT_FOUR.n_actions == GameEnv("connect-four").action_space.n
    assert TIC_TAC_TOE.rows == 3
