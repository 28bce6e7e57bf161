"""DQN's loss and PPO's objective as their equations, on cases the other tests skip."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from policylab.deep.common.checkpoint import (
    FORMAT,
    VERSION,
    load_checkpoint,
    save_checkpoint,
)
from policylab.deep.dqn.losses import q_learning_targets, td_loss
from policylab.deep.ppo.losses import clipped_surrogate_loss


def test_huber_td_loss_is_quadratic_inside_1_and_linear_outside() -> None:
    """Huber with delta 1: 0.5 delta^2 for |delta| <= 1, |delta| - 0.5 beyond (Mnih et al.
    2015 clip the error's gradient to [-1, 1]); the mean is weighted by the importance
    weights of prioritized replay."""
    delta = torch.tensor([0.5, -0.5, 2.0, -3.0])
    per = torch.tensor([0.125, 0.125, 1.5, 2.5])
    ones = torch.ones(4)
    torch.testing.assert_close(td_loss(delta, ones), per.mean())
    w = torch.tensor([1.0, 0.0, 0.5, 2.0])
    torch.testing.assert_close(td_loss(delta, w), (w * per).mean())
    torch.testing.assert_close(td_loss(delta, w, kind="mse"), (w * delta**2).mean())
    # The gradient of the Huber loss is the error clipped to [-1, 1], times w / B.
    d = delta.clone().requires_grad_(True)
    td_loss(d, w).backward()
    assert d.grad is not None
    torch.testing.assert_close(d.grad, w * delta.clamp(-1.0, 1.0) / 4)


def test_targets_use_the_stored_bootstrap_weight() -> None:
    """y = G + d max_a Q_target(S', a), with d = 0 after a termination."""
    returns = torch.tensor([1.0, 1.0])
    discounts = torch.tensor([0.0, 0.81])
    q_target = torch.tensor([[5.0, 7.0], [2.0, -1.0]])
    y = q_learning_targets(returns, discounts, q_target, None)
    torch.testing.assert_close(y, torch.tensor([1.0, 1.0 + 0.81 * 2.0]))


@pytest.mark.parametrize("adv", [1.0, -1.0])
def test_clipped_objective_is_flat_outside_the_clip_range_in_the_direction_it_favours(
    adv: float,
) -> None:
    """min(r A, clip(r, 1 - eps, 1 + eps) A): for A > 0 the objective stops growing at
    r = 1 + eps; for A < 0 at r = 1 - eps. Beyond, the gradient in r is 0."""
    eps = 0.2
    far = 1.0 + 3 * eps if adv > 0 else 1.0 - 3 * eps
    r = torch.tensor([far], requires_grad=True)
    loss = clipped_surrogate_loss(r, torch.tensor([adv]), eps)
    edge = 1.0 + eps if adv > 0 else 1.0 - eps
    torch.testing.assert_close(loss, torch.tensor(-edge * adv))
    loss.backward()
    assert r.grad is not None and r.grad.item() == 0.0


@pytest.mark.parametrize("version", [VERSION + 1, VERSION - 1, None])
def test_checkpoint_of_another_format_version_is_refused(tmp_path: Path, version: object) -> None:
    """A file in policylab's format but of another format version is not read as if it
    were this one (its fields may mean something else): a clear CheckpointError."""
    from policylab.exceptions import CheckpointError

    good = tmp_path / "good.pt"
    save_checkpoint(good, {"step": 3}, {"w": torch.ones(2)})
    meta, tensors = load_checkpoint(good)
    assert meta == {"step": 3}
    torch.testing.assert_close(tensors["w"], torch.ones(2))
    other = tmp_path / "other.pt"
    torch.save({"format": FORMAT, "version": version, "meta": "{}", "tensors": {}}, other)
    with pytest.raises(CheckpointError, match="checkpoint version"):
        load_checkpoint(other)
