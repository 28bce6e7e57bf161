"""The hand-written MLP backward pass against autograd, and the flat parameter buffer."""

from __future__ import annotations

import gymnasium as gym
import pytest
import torch
from torch import nn

from policylab.deep.common.mlp_grad import (
    ChainPasses,
    FlatParameters,
    mlp_layers,
)
from policylab.deep.common.networks import MLP, build_torso
from policylab.deep.ppo.losses import (
    clipped_surrogate_loss,
    clipped_surrogate_loss_grad,
    value_loss,
    value_loss_grad,
)
from policylab.exceptions import InvalidArgumentError


@pytest.mark.parametrize("act", ["tanh", "relu", "elu"])
def test_chain_passes_on_the_layers_own_tensors_equal_autograd(act: str) -> None:
    # parameters not laid out as blocks: each forward copies them, each backward writes .grad
    g = torch.Generator().manual_seed(0)
    net = nn.Sequential(
        build_torso(gym.spaces.Box(-1, 1, (3, 2)), (7, 5), act, g), MLP(5, (), 4, generator=g)
    ).double()
    chain = mlp_layers(net)
    assert chain is not None and [lin.out_features for lin in chain] == [7, 5, 4]
    x = torch.randn(11, 3, 2, dtype=torch.float64, generator=g)
    w = torch.randn(11, 4, dtype=torch.float64, generator=g)
    loss = (torch.sin(net(x)) * w).sum()  # any loss of the output
    loss.backward()  # type: ignore[no-untyped-call]
    expected = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
    passes = ChainPasses(chain, act)
    out = passes.forward(passes.with_ones(x))
    torch.testing.assert_close(out, net(x).detach(), rtol=0, atol=1e-12)
    net.zero_grad(set_to_none=True)
    passes.backward(torch.cos(out) * w)
    for p, e in zip(net.parameters(), expected, strict=True):
        torch.testing.assert_close(p.grad, e, rtol=0, atol=1e-12)
    # a gradient already there is overwritten, not added to; only the first rows count
    passes.forward(passes.with_ones(torch.cat([x, x.flip(0)])))
    passes.backward(torch.cos(out) * w, rows=len(x))
    for p, e in zip(net.parameters(), expected, strict=True):
        torch.testing.assert_close(p.grad, e, rtol=0, atol=1e-12)


@pytest.mark.parametrize("act", ["tanh", "relu", "elu"])
def test_chain_passes_on_weight_and_bias_blocks_equal_autograd(act: str) -> None:
    # 6 -> 9 -> 8 -> 2: the head's narrow gradient takes the transposed product
    g = torch.Generator().manual_seed(1)
    net = MLP(6, (9, 8), 2, act, generator=g).double()
    chain = mlp_layers(net)
    assert chain is not None
    before = [p.detach().clone() for p in net.parameters()]
    flat = FlatParameters(list(net.parameters()), chain)
    assert all(torch.equal(p, b) for p, b in zip(net.parameters(), before, strict=True))
    block = flat.blocks(flat.flat.detach())[1]  # [W^T; b] of the middle layer
    assert torch.equal(block[:-1], chain[1].weight.t()) and torch.equal(block[-1], chain[1].bias)
    passes = ChainPasses(flat, act)
    for batch in (5, 13, 5):  # buffers per batch size, reused
        x = torch.randn(batch, 6, dtype=torch.float64, generator=g)
        w = torch.randn(batch, 2, dtype=torch.float64, generator=g)
        net.zero_grad(set_to_none=False)
        (torch.sin(net(x)) * w).sum().backward()  # type: ignore[no-untyped-call]
        expected = [p.grad.clone() for p in net.parameters()]  # type: ignore[union-attr]
        flat.flat.grad.fill_(7.0)  # type: ignore[union-attr]  # overwritten, not added to
        out = passes.forward(passes.with_ones(x))
        torch.testing.assert_close(out, net(x).detach(), rtol=0, atol=1e-12)
        passes.backward(torch.cos(out) * w)
        for p, e in zip(net.parameters(), expected, strict=True):
            torch.testing.assert_close(p.grad, e, rtol=0, atol=1e-12)


def test_chain_layout_keeps_optimizer_state_in_checkpoints_as_concatenated() -> None:
    net = MLP(3, (4,), 2, generator=torch.Generator().manual_seed(0))
    chain = mlp_layers(net)
    assert chain is not None
    with pytest.raises(InvalidArgumentError, match="chain's weights and biases"):
        FlatParameters(list(net.parameters())[::-1], chain)
    flat = FlatParameters(list(net.parameters()), chain)
    opt = torch.optim.Adam([flat.flat], lr=0.1)
    flat.flat.grad.copy_(torch.arange(flat.flat.numel(), dtype=torch.float32))  # type: ignore[union-attr]
    opt.step()
    state = opt.state_dict()
    saved = flat.state_for_checkpoint(state)
    moments = state["state"][0]["exp_avg"]
    torch.testing.assert_close(  # the parameters one after the other, row-major
        saved["state"][0]["exp_avg"],
        torch.cat([flat.view(moments, i).reshape(-1) for i in range(4)]),
        rtol=0,
        atol=0,
    )
    back = flat.state_from_per_parameter(saved)
    for key in ("exp_avg", "exp_avg_sq"):
        assert torch.equal(back["state"][0][key], state["state"][0][key])
    # a per-parameter state (older checkpoints) lands in the same places
    per = {
        "state": {i: {"step": state["state"][0]["step"], "exp_avg": flat.view(moments, i).clone()}
                  for i in range(4)},
        "param_groups": [{**state["param_groups"][0], "params": [0, 1, 2, 3]}],
    }  # fmt: skip
    assert torch.equal(flat.state_from_per_parameter(per)["state"][0]["exp_avg"], moments)


def test_mlp_layers_refuses_what_is_not_a_plain_mlp() -> None:
    assert mlp_layers(nn.Linear(3, 2)) is not None
    assert mlp_layers(nn.Linear(3, 2), nn.Linear(2, 2)) is None  # no activation between
    assert mlp_layers(nn.Linear(3, 2), nn.Tanh()) is None  # activation after the output
    assert mlp_layers(nn.Conv2d(1, 1, 3)) is None
    assert mlp_layers(build_torso(gym.spaces.Discrete(4), (8,), "tanh", None)) is None


def test_ppo_loss_gradients_equal_autograd_including_ties() -> None:
    # ratios inside, outside and exactly on the clip range; value errors on both sides
    ratio = torch.tensor([0.5, 0.8, 1.0, 1.1, 1.2, 1.5, 1.5, 0.7], dtype=torch.float64)
    adv = torch.tensor([1.0, -1.0, 0.5, -2.0, 1.0, 1.0, -1.0, 0.0], dtype=torch.float64)
    r = ratio.clone().requires_grad_()
    clipped_surrogate_loss(r, adv, 0.2).backward()  # type: ignore[no-untyped-call]
    loss, grad = clipped_surrogate_loss_grad(ratio, adv, 0.2)
    torch.testing.assert_close(loss, clipped_surrogate_loss(ratio, adv, 0.2))
    torch.testing.assert_close(grad, r.grad, rtol=0, atol=1e-15)
    v = torch.tensor([0.0, 1.0, 2.0, 0.5, -1.0, 0.3, 0.25, 3.0], dtype=torch.float64)
    old = torch.tensor([0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5], dtype=torch.float64)
    ret = torch.tensor([1.0, 0.0, 0.4, 0.5, 2.0, 0.2, 0.25, -1.0], dtype=torch.float64)
    for clip in (None, 0.5, 0.25):
        vv = v.clone().requires_grad_()
        value_loss(vv, old, ret, clip).backward()  # type: ignore[no-untyped-call]
        loss, grad = value_loss_grad(v, old, ret, clip)
        torch.testing.assert_close(loss, value_loss(v, old, ret, clip))
        torch.testing.assert_close(grad, vv.grad, rtol=0, atol=1e-15)


def test_flat_parameters_are_views_and_old_optimizer_state_converts() -> None:
    net = MLP(3, (4,), 2, generator=torch.Generator().manual_seed(0))
    before = [p.detach().clone() for p in net.parameters()]
    flat = FlatParameters(list(net.parameters()))
    for p, b in zip(net.parameters(), before, strict=True):
        assert torch.equal(p, b) and p.data_ptr() != b.data_ptr()
    with torch.no_grad():
        flat.flat.add_(1.0)
    assert all(torch.equal(p, b + 1) for p, b in zip(net.parameters(), before, strict=True))
    # an optimizer with one state per parameter (the layout before flattening) ...
    per = torch.optim.Adam(list(net.parameters()), lr=0.1)
    for p in net.parameters():
        p.grad = torch.randn_like(p)
    per.step()
    one = torch.optim.Adam([flat.flat], lr=0.1)
    one.load_state_dict(flat.state_from_per_parameter(per.state_dict()))
    state = one.state_dict()["state"][0]
    old = per.state_dict()["state"]
    for key in ("exp_avg", "exp_avg_sq"):
        torch.testing.assert_close(state[key], torch.cat([old[i][key].reshape(-1) for i in old]))
    assert float(state["step"]) == 1.0
    # ... and a flat one is left alone
    assert flat.state_from_per_parameter(one.state_dict()) == one.state_dict()


def test_fused_adam_step_and_flat_clip_equal_the_optimizer_bit_for_bit() -> None:
    import copy

    from policylab.deep.common.mlp_grad import fused_adam_step
    from policylab.deep.common.networks import clip_grad_norm

    gen = torch.Generator().manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(4, 16), torch.nn.Tanh(), torch.nn.Linear(16, 2))
    net2 = copy.deepcopy(net)
    f1, f2 = FlatParameters(list(net.parameters())), FlatParameters(list(net2.parameters()))
    o1 = torch.optim.Adam([f1.flat], lr=1e-2, eps=1e-5, fused=True)
    o2 = torch.optim.Adam([f2.flat], lr=1e-2, eps=1e-5, fused=True)
    for i in range(6):
        x = torch.randn(8, 4, generator=gen) * (10.0 if i % 2 else 0.1)  # clipped, unclipped
        for m, f in ((net, f1), (net2, f2)):
            f.flat.grad.zero_()  # type: ignore[union-attr]
            (m(x) ** 2).sum().backward()  # type: ignore[no-untyped-call]
        norm = clip_grad_norm([f1.flat], 1.0)
        o1.step()
        assert float(f2.clip_grad_norm_(1.0)) == norm
        fused_adam_step(o2)
        assert torch.equal(f1.flat, f2.flat)
        for o in (o1, o2):
            o.param_groups[0]["lr"] = 1e-2 * (1 - i / 6)  # an annealed rate is read each step
    s1, s2 = o1.state_dict()["state"][0], o2.state_dict()["state"][0]
    assert all(torch.equal(s1[k], s2[k]) for k in ("step", "exp_avg", "exp_avg_sq"))


@pytest.mark.parametrize("act", ["tanh", "relu", "elu"])
def test_numpy_forward_equals_chain_passes_and_follows_the_parameters(act: str) -> None:
    import numpy as np

    from policylab.deep.common.mlp_grad import NumpyMLP

    g = torch.Generator().manual_seed(1)
    net = nn.Sequential(build_torso(gym.spaces.Box(-1, 1, (3,)), (16, 8), act, g), nn.Linear(8, 3))
    chain = mlp_layers(net)
    assert chain is not None
    fwd, passes = NumpyMLP(chain, act), ChainPasses(chain, act)
    x = torch.randn(5, 3, generator=g)
    torch.testing.assert_close(
        torch.from_numpy(fwd(x.numpy())),
        passes.forward(passes.with_ones(x), keep=False),
        rtol=1e-6,
        atol=1e-6,
    )
    with torch.no_grad():  # an in-place update (an optimizer step) is seen
        chain[1].weight.mul_(-2.0)
    flat = FlatParameters(list(net.parameters()))  # and so is memory that moved
    with torch.no_grad():
        flat.flat.add_(0.1)
    expected = passes.forward(passes.with_ones(x), keep=False)
    torch.testing.assert_close(torch.from_numpy(fwd(x.numpy())), expected, rtol=1e-6, atol=1e-6)
    assert fwd(np.zeros((0, 3), np.float32)).shape == (0, 3)


@pytest.mark.parametrize("stacked", [False, True])
@pytest.mark.parametrize(("rows", "inner", "cols"), [
    (256, 257, 1), (256, 257, 6), (64, 65, 2), (512, 257, 16), (40, 65, 12),
    (256, 1, 257), (3, 9, 2), (256, 257, 17), (8, 5, 1),
])  # fmt: skip
def test_products_of_every_shape_equal_the_plain_product(
    stacked: bool, rows: int, inner: int, cols: int
) -> None:
    # the narrow results computed as wide ones (b^T a^T)^T, outer products as broadcast
    # multiplications: the plain product's numbers, into a strided out= as well
    from policylab.deep.common.mlp_grad import _mm

    g = torch.Generator().manual_seed(rows + inner + cols)
    k = (2,) if stacked else ()
    a = torch.randn(*k, rows, inner, generator=g, dtype=torch.float64)
    # b as the blocks hold it: columns of a wider matrix, so a strided view
    b = torch.randn(*k, inner, 2 * cols, generator=g, dtype=torch.float64)[..., :cols]
    c = _mm(a, b)
    assert c.shape == (*k, rows, cols) and c.is_contiguous()
    expected = torch.matmul(a, b)
    if inner == 1:  # one multiplication per element: bit for bit
        assert torch.equal(c, expected)
    torch.testing.assert_close(c, expected, rtol=1e-12, atol=1e-12)
    buffer = torch.zeros(*k, rows, cols + 1, dtype=torch.float64)
    assert _mm(a, b, out=buffer[..., :-1]).data_ptr() == buffer.data_ptr()
    torch.testing.assert_close(buffer[..., :-1], expected, rtol=1e-12, atol=1e-12)
    assert torch.all(buffer[..., -1] == 0)
    if stacked:  # a 2-d operand is shared by the stacked networks
        torch.testing.assert_close(_mm(a[0], b), torch.matmul(a[0], b), rtol=1e-12, atol=1e-12)


def test_narrow_output_layer_equals_the_plain_product() -> None:
    # a 2-4 output layer on batches of any size, on blocks: the same numbers
    g = torch.Generator().manual_seed(2)
    net = nn.Sequential(nn.Linear(6, 32), nn.ReLU(), nn.Linear(32, 3))
    chain = mlp_layers(net)
    assert chain is not None
    FlatParameters.of_chain(chain)
    passes = ChainPasses(chain, "relu")
    for batch in (1, 31, 32, 200):
        x = torch.randn(batch, 6, generator=g)
        out = passes.forward(passes.with_ones(x), keep=False)
        assert out.is_contiguous() and out.shape == (batch, 3)
        torch.testing.assert_close(out, net(x).detach(), rtol=1e-6, atol=1e-6)


def test_moments_loaded_into_block_views_are_laid_out_as_their_parameters() -> None:
    # a fused Adam reads a parameter and its moments as flat memory: a row-major moment
    # (a checkpoint of the layer's own tensors) under a transposed block view needs a copy
    import copy

    from policylab.deep.common.mlp_grad import match_state_layout

    g = torch.Generator().manual_seed(4)
    net, ref = nn.Linear(4, 3), nn.Linear(4, 3)
    ref.load_state_dict(net.state_dict())
    FlatParameters.of_chain([net])
    assert net.weight.stride() == (1, 3)  # W is a transposed view of [W^T; b]
    ref_opt = torch.optim.Adam(ref.parameters(), lr=0.1, fused=True)
    opt = torch.optim.Adam(net.parameters(), lr=0.1, fused=True)
    for step in range(4):
        grads = [torch.randn(p.shape, generator=g) for p in ref.parameters()]
        for p, q, grad in zip(ref.parameters(), net.parameters(), grads, strict=True):
            p.grad = grad
            q.grad.copy_(grad)  # type: ignore[union-attr]
        ref_opt.step()
        if step == 0:
            with torch.no_grad():
                for p, q in zip(net.parameters(), ref.parameters(), strict=True):
                    p.copy_(q)
            opt.load_state_dict(copy.deepcopy(ref_opt.state_dict()))  # as from a file
            match_state_layout(opt)
            assert opt.state[net.weight]["exp_avg"].stride() == (1, 3)
        else:
            opt.step()
    for p, q in zip(net.parameters(), ref.parameters(), strict=True):
        torch.testing.assert_close(p, q, rtol=0, atol=1e-6)


def test_fused_adam_step_on_block_views_is_the_per_parameter_step() -> None:
    # parameters, gradients and moments that are views of one tensor each step as that
    # tensor: the same elementwise arithmetic as Adam on the layers' own tensors (the
    # kernel's vectorised and scalar loops may round a moment differently in the last place)
    from policylab.deep.common.mlp_grad import _FLAT_GROUPS, fused_adam_step

    g = torch.Generator().manual_seed(6)
    net = MLP(5, (7,), 3, "relu", generator=g)
    ref = MLP(5, (7,), 3, "relu", generator=g)
    ref.load_state_dict(net.state_dict())
    chain = mlp_layers(net)
    assert chain is not None
    FlatParameters.of_chain(chain)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2, fused=True)
    ref_opt = torch.optim.Adam(ref.parameters(), lr=1e-2, fused=True)
    for _ in range(4):
        for p, q in zip(net.parameters(), ref.parameters(), strict=True):
            q.grad = torch.randn(q.shape, generator=g)
            p.grad.copy_(q.grad)  # type: ignore[union-attr]
        fused_adam_step(opt)
        ref_opt.step()
        for p, q in zip(net.parameters(), ref.parameters(), strict=True):
            torch.testing.assert_close(p, q, rtol=1e-6, atol=1e-7)
    # after the first step the moments were moved into one tensor: one update per group
    assert next(iter(_FLAT_GROUPS[opt][0].values())) is not None
    moments = [opt.state[p]["exp_avg"] for p in net.parameters()]
    assert len({m.untyped_storage().data_ptr() for m in moments}) == 1
    for p, q in zip(net.parameters(), ref.parameters(), strict=True):
        for key in ("exp_avg", "exp_avg_sq"):
            torch.testing.assert_close(opt.state[p][key], ref_opt.state[q][key], rtol=1e-6, atol=0)
