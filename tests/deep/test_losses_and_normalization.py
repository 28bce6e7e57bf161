"""PPO's loss equations and the running normalisers against hand computation."""

from __future__ import annotations

import numpy as np
import torch

from policylab.deep import ObservationNormalizer, RewardScaler, RunningMeanStd
from policylab.deep.ppo.losses import clipped_surrogate_loss, normalized, value_loss


def test_clipped_surrogate_hand_computed() -> None:
    ratio = torch.tensor([0.5, 1.0, 1.5, 1.5])
    adv = torch.tensor([1.0, 2.0, 1.0, -1.0])
    # min(r A, clip(r, .8, 1.2) A): 0.5, 2.0, 1.2, -1.5
    expected = -(0.5 + 2.0 + 1.2 - 1.5) / 4
    torch.testing.assert_close(clipped_surrogate_loss(ratio, adv, 0.2), torch.tensor(expected))


def test_value_loss_with_and_without_clipping() -> None:
    v, old, ret = torch.tensor([2.0, 0.0]), torch.tensor([1.0, 0.5]), torch.tensor([3.0, 1.0])
    torch.testing.assert_close(value_loss(v, old, ret, None), torch.tensor((1.0 + 1.0) / 2))
    # clipped values: 1 + clip(1, -.5, .5) = 1.5 and 0.5 + clip(-.5, -.5, .5) = 0
    # max((2-3)^2, (1.5-3)^2) = 2.25; max((0-1)^2, (0-1)^2) = 1
    torch.testing.assert_close(value_loss(v, old, ret, 0.5), torch.tensor((2.25 + 1.0) / 2))


def test_advantage_normalization() -> None:
    x = torch.tensor([1.0, 2.0, 3.0, 4.0])
    z = normalized(x)
    torch.testing.assert_close(z.mean(), torch.tensor(0.0))
    torch.testing.assert_close(z.std(), torch.tensor(1.0), atol=1e-6, rtol=0)


def test_running_mean_std_matches_numpy_on_all_batches() -> None:
    rng = np.random.default_rng(0)
    batches = [rng.normal(3.0, 2.0, size=(n, 2)) for n in (5, 17, 1, 40)]
    rms = RunningMeanStd((2,))
    for b in batches:
        rms.update(b)
    allx = np.concatenate(batches)
    np.testing.assert_allclose(rms.mean, allx.mean(0), rtol=1e-4)
    np.testing.assert_allclose(rms.var, allx.var(0), rtol=1e-4)


def test_observation_normalizer_clips() -> None:
    norm = ObservationNormalizer((1,), clip=2.0)
    norm(np.array([[0.0], [2.0]]), update=True)
    out = norm(np.array([[1.0], [100.0]]))
    np.testing.assert_allclose(out[:, 0], [0.0, 2.0], atol=1e-3)


def test_reward_scaler_divides_by_return_std_and_resets_at_episode_ends() -> None:
    s = RewardScaler(1, gamma=0.5)
    s(np.array([1.0]), np.array([False]))
    assert s.ret[0] == 1.0
    out = s(np.array([1.0]), np.array([True]))
    assert s.ret[0] == 0.0  # the tracked return restarts with the next episode
    np.testing.assert_allclose(out, 1.0 / np.sqrt(s.rms.var + 1e-8), rtol=1e-6)
