"""The hand-written backward passes of SAC and TD3 against autograd's gradients."""

from __future__ import annotations

import copy
import math

import pytest
import torch

import policylab as pl
from policylab.deep.common.losses import (
    clipped_double_q_targets,
    polyak_update,
    twin_q_loss,
    twin_q_loss_grad,
)
from policylab.deep.common.mlp_grad import fused_adam_step
from policylab.deep.common.networks import TwinQNetwork
from policylab.deep.common.off_policy import twin_q_passes
from policylab.deep.sac.losses import (
    entropy_coef_loss,
    entropy_coef_loss_grad,
    sac_actor_loss,
    sac_actor_loss_grad,
    squashed_gaussian_grad,
    squashed_gaussian_log_prob,
)
from policylab.deep.td3.losses import smoothed_target_actions, td3_actor_loss, td3_actor_loss_grad


def _gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


@pytest.mark.parametrize(("hidden", "act"), [((8, 5), "relu"), ((7,), "tanh"), ((6, 5, 4), "elu")])
def test_twin_q_backward_is_autograds(hidden: tuple[int, ...], act: str) -> None:
    net = TwinQNetwork(3, 2, hidden, act, _gen(1))
    with torch.no_grad():  # nonzero biases, so that their gradients are tested too
        for b in net.biases:
            b.normal_(generator=_gen(2))
    obs = torch.randn(6, 3, generator=_gen(3))
    act_in = torch.randn(6, 2, generator=_gen(4)).requires_grad_()
    dq = torch.randn(2, 6, generator=_gen(5))
    q = net(obs, act_in)
    (q * dq).sum().backward()
    want = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
    passes, x = twin_q_passes(net), torch.cat([obs, act_in.detach(), torch.ones(6, 1)], 1)
    actions = slice(3, -1)  # the action's columns of [s, a, 1]
    q_hand = passes.forward(x)[..., 0]
    torch.testing.assert_close(q_hand, q.detach())
    for p in net.parameters():
        p.grad = torch.full_like(p, 7.0)  # overwritten, not added to
    grad_action = passes.backward(dq.unsqueeze(-1), input_grad=actions)
    for p, w in zip(net.parameters(), want, strict=True):
        torch.testing.assert_close(p.grad, w)
    torch.testing.assert_close(grad_action, act_in.grad)
    for p in net.parameters():  # and without .grad: laid out as the blocks
        p.grad = None
    passes.forward(x)
    passes.backward(dq.unsqueeze(-1))
    for p, w in zip(net.parameters(), want, strict=True):
        torch.testing.assert_close(p.grad, w)
        assert p.grad.stride() == p.stride()  # type: ignore[union-attr]
    # Q_1 alone (the first of the stacked blocks), critics held constant: no parameter
    # gradients
    q1 = passes.forward(x, first=1)[..., 0]
    torch.testing.assert_close(q1, q.detach()[:1])
    before = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
    g1 = passes.backward(dq[:1].unsqueeze(-1), param_grads=False, input_grad=actions)
    for p, b in zip(net.parameters(), before, strict=True):
        torch.testing.assert_close(p.grad, b)
    act_in.grad = None
    (net(obs, act_in)[0] * dq[0]).sum().backward()
    torch.testing.assert_close(g1, act_in.grad)


def test_loss_gradients_are_autograds() -> None:
    q = torch.randn(2, 5, generator=_gen(0)).requires_grad_()
    y = torch.randn(5, generator=_gen(1))
    twin_q_loss(q, y).backward()
    torch.testing.assert_close(twin_q_loss_grad(q.detach(), y), q.grad)
    # by hand: (Q - y) / B
    torch.testing.assert_close(
        twin_q_loss_grad(torch.tensor([[1.0, 2.0], [3.0, 0.0]]), torch.tensor([2.0, 2.0])),
        torch.tensor([[-0.5, 0.0], [0.5, -1.0]]),
    )
    log_prob = torch.randn(5, generator=_gen(2)).requires_grad_()
    q.grad = None
    sac_actor_loss(log_prob, q, 0.3).backward()
    g_lp, g_q = sac_actor_loss_grad(log_prob.detach(), q.detach(), 0.3)
    torch.testing.assert_close(g_lp, log_prob.grad)
    torch.testing.assert_close(g_q, q.grad)
    log_alpha = torch.tensor(math.log(0.5), requires_grad=True)
    entropy_coef_loss(log_alpha, log_prob.detach(), -2.0).backward()
    torch.testing.assert_close(entropy_coef_loss_grad(log_prob.detach(), -2.0), log_alpha.grad)
    q1 = torch.randn(1, 5, generator=_gen(3)).requires_grad_()
    td3_actor_loss(q1[0]).backward()
    torch.testing.assert_close(td3_actor_loss_grad(q1.detach()), q1.grad)


def test_squashed_gaussian_grad_is_autograds() -> None:
    mean = torch.randn(7, 3, generator=_gen(0)).requires_grad_()
    log_std = (0.5 * torch.randn(7, 3, generator=_gen(1))).requires_grad_()
    eps = torch.randn(7, 3, generator=_gen(2))
    noise = log_std.exp() * eps
    u = mean + noise
    a = torch.tanh(u)
    log_prob = squashed_gaussian_log_prob(u, mean, log_std)
    g_a = torch.randn(7, 3, generator=_gen(3))
    g_lp = torch.randn(7, generator=_gen(4))
    ((a * g_a).sum() + (log_prob * g_lp).sum()).backward()
    g_mean, g_log_std = squashed_gaussian_grad(a.detach(), noise.detach(), g_a, g_lp)
    torch.testing.assert_close(g_mean, mean.grad)
    torch.testing.assert_close(g_log_std, log_std.grad)


def test_adam_step_is_step_bit_for_bit() -> None:
    ps = [torch.randn(4, 3, generator=_gen(i)).requires_grad_() for i in range(2)]
    qs = [p.detach().clone().requires_grad_() for p in ps]
    opt_p = torch.optim.Adam(ps, lr=1e-2, fused=True)
    opt_q = torch.optim.Adam(qs, lr=1e-2, fused=True)
    for i in range(4):
        for p, q in zip(ps, qs, strict=True):
            p.grad = torch.randn(4, 3, generator=_gen(10 + i))
            q.grad = p.grad.clone()
        opt_p.step()
        fused_adam_step(opt_q)
        for p, q in zip(ps, qs, strict=True):
            torch.testing.assert_close(p, q, rtol=0, atol=0)
    assert opt_q.state_dict()["state"][0]["step"] == 4


def test_sac_update_is_the_autograd_update() -> None:
    """One hand-written SAC update gives the parameters of the same update by autograd."""
    agent = pl.deep.SAC("Pendulum-v1", seed=0, hidden=(16, 16), batch_size=32, learning_starts=64)
    agent.learn(100)  # past learning_starts: Adam has state
    ref = copy.deepcopy(agent)
    batch = agent.replay.sample(32)
    stats = agent._train_step(batch)

    obs, actions, rewards, next_obs, discounts = ref._batch_tensors(batch)
    alpha = ref.log_alpha.detach().exp()
    features = ref.actor.features(torch.cat([obs, next_obs]))
    all_a, all_lp, _, _ = ref.actor.reparameterised(features, ref.torch_gen)
    with torch.no_grad():
        next_q = ref.critic_target(next_obs, all_a[32:])
        y = clipped_double_q_targets(rewards, discounts, next_q, all_lp[32:], alpha)
    critic_loss = twin_q_loss(ref.critic(obs, actions), y)
    ref.critic_optimizer.zero_grad()
    critic_loss.backward()
    ref.critic_optimizer.step()
    q_pi = ref.critic(obs, all_a[:32], [p.detach() for p in ref.critic.parameters()])
    actor_loss = sac_actor_loss(all_lp[:32], q_pi, alpha)
    alpha_loss = entropy_coef_loss(ref.log_alpha, all_lp[:32], ref.target_entropy)
    ref.actor_optimizer.zero_grad()
    (actor_loss + alpha_loss).backward()
    ref.actor_optimizer.step()
    polyak_update(ref._target_params, ref._critic_params, ref.config.tau)

    for name in ("actor", "critic", "critic_target"):
        for p, r in zip(
            getattr(agent, name).parameters(), getattr(ref, name).parameters(), strict=True
        ):
            torch.testing.assert_close(p, r)
    torch.testing.assert_close(agent.log_alpha, ref.log_alpha)
    torch.testing.assert_close(stats["critic_loss"], critic_loss.detach())
    torch.testing.assert_close(stats["actor_loss"], actor_loss.detach())
    torch.testing.assert_close(stats["ent_coef_loss"], alpha_loss.detach())


def test_td3_update_is_the_autograd_update() -> None:
    """50 hand-written TD3 updates equal autograd's with torch's own Adam step.

    Many updates, not one: the fast path's cached flat views (the optimizers' one-tensor
    step, the Polyak averages' whole tensors) must keep following the parameters, and the
    delayed actor step must come every ``policy_delay`` updates.
    """
    agent = pl.deep.TD3("Pendulum-v1", seed=0, hidden=(16, 16), batch_size=32, learning_starts=64)
    agent.learn(100)
    ref = copy.deepcopy(agent)
    batches = [agent.replay.sample(32) for _ in range(50)]
    stats = [agent._train_step(b) for b in batches]
    cfg = ref.config
    for i, batch in enumerate(batches):
        obs, actions, rewards, next_obs, discounts = ref._batch_tensors(batch)
        noise = cfg.target_policy_noise * torch.randn(actions.shape, generator=ref.torch_gen)
        with torch.no_grad():
            a2 = smoothed_target_actions(ref.actor_target(next_obs), noise, cfg.target_noise_clip)
            y = clipped_double_q_targets(rewards, discounts, ref.critic_target(next_obs, a2))
        critic_loss = twin_q_loss(ref.critic(obs, actions), y)
        ref.critic_optimizer.zero_grad()
        critic_loss.backward()
        ref.critic_optimizer.step()
        torch.testing.assert_close(stats[i]["critic_loss"], critic_loss.detach())
        ref.n_updates += 1
        if ref.n_updates % cfg.policy_delay == 0:
            detached = [p.detach()[:1] for p in ref.critic.parameters()]
            actor_loss = td3_actor_loss(ref.critic(obs, ref.actor(obs), detached)[0])
            ref.actor_optimizer.zero_grad()
            actor_loss.backward()
            ref.actor_optimizer.step()
            polyak_update(
                ref._actor_target_params + ref._target_params,
                ref._actor_params + ref._critic_params,
                cfg.tau,
            )
            torch.testing.assert_close(stats[i]["actor_loss"], actor_loss.detach())
    assert sum("actor_loss" in s for s in stats) == 25
    for name in ("actor", "actor_target", "critic", "critic_target"):
        for p, r in zip(
            getattr(agent, name).parameters(), getattr(ref, name).parameters(), strict=True
        ):
            torch.testing.assert_close(p, r)


def test_polyak_averages_run_over_whole_tensors_and_follow_the_parameters() -> None:
    # a network and its target copy laid out alike: one lerp over each pair of tensors
    sac = pl.deep.SAC("Pendulum-v1", seed=0, hidden=(8, 8))
    with torch.no_grad():
        for p in sac.critic.parameters():
            p.add_(1.0)
    before = [p.detach().clone() for p in sac.critic_target.parameters()]
    sac._polyak_update(sac._target_params, sac._critic_params)
    (pair,) = sac._polyak_operands.values()
    assert len(pair[0]) == len(pair[1]) == 1  # one tensor each
    tau = sac.config.tau
    for t, p, b in zip(
        sac.critic_target.parameters(), sac.critic.parameters(), before, strict=True
    ):
        torch.testing.assert_close(t, b + tau * (p - b))
    # a copy of the agent averages its own tensors
    copied = copy.deepcopy(sac)
    with torch.no_grad():
        for p in copied.critic.parameters():
            p.add_(1.0)
    before = [p.detach().clone() for p in copied.critic_target.parameters()]
    copied._polyak_update(copied._target_params, copied._critic_params)
    for t, p, b in zip(
        copied.critic_target.parameters(), copied.critic.parameters(), before, strict=True
    ):
        torch.testing.assert_close(t, b + tau * (p - b))


def test_first_critic_alone_gives_no_parameter_gradients() -> None:
    from policylab.exceptions import InvalidArgumentError

    net = TwinQNetwork(3, 2, (4,), "relu", _gen(0))
    passes = twin_q_passes(net)
    passes.forward(torch.ones(5, 6), first=1)
    with pytest.raises(InvalidArgumentError, match="param_grads=False"):
        passes.backward(torch.ones(1, 5, 1))
