"""Backpropagation through a plain MLP written out by hand, for small networks.

With 64x64 networks on minibatches of 64-256 samples the arithmetic of a gradient step
takes microseconds and autograd's bookkeeping (building the graph, one node per
operation, the engine walking it back) costs more than the matrix products. For a chain
``Linear, act, Linear, act, ..., Linear`` the backward pass is a few lines of linear
algebra, the same products autograd runs:

    forward:   h_0 = x,   z_l = h_{l-1} W_l^T + b_l,   h_l = act(z_l)   (no act on the last)
    backward:  dW_l = dz_l^T h_{l-1},   db_l = sum_batch dz_l,
               dz_{l-1} = (dz_l W_l) * act'(z_{l-1})

with act' written in terms of the layer's output h (tanh: 1 - h^2; ReLU: [h > 0];
ELU: h + 1 where h <= 0, else 1), computed by the same kernels autograd calls. One
kernel differs: tanh is NumPy's, applied in place to the tensor's memory, because
torch's CPU tanh costs about 20 times as much on a (256, 64) batch on the AVX-512
machine of the benchmarks (73 us against 3.3 us); both are accurate to a few units in
the last place, so results agree with the autograd path to float rounding.
:func:`mlp_layers` finds such a chain in a module; networks it does not recognise
(convolutions, one-hot inputs) keep autograd.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from policylab.deep.common.networks import MLP
from policylab.exceptions import InvalidArgumentError

__all__ = [
    "FlatParameters",
    "LinearChain",
    "NumpyMLP",
    "activation_backward",
    "fused_adam_step",
    "mlp_backward",
    "mlp_forward",
    "mlp_layers",
]

LinearChain = list[nn.Linear]
"""The Linear layers of an MLP in order; an activation follows each but the last."""


def mlp_layers(*modules: nn.Module) -> LinearChain | None:
    """The Linear layers of ``modules`` run one after the other, if they form a plain MLP.

    Accepts :class:`~policylab.deep.common.networks.MLP`, ``nn.Linear``, ``nn.Flatten``
    and ``nn.Sequential`` of those (a torso from ``build_torso`` on a vector space and
    the heads on top of it). Returns None for anything else (a CNN, a one-hot input),
    and where an activation would be missing between two Linear layers or present
    after the last one.
    """
    linears: LinearChain = []
    acts: list[bool] = []  # after each Linear: is an activation applied?

    def walk(m: nn.Module) -> bool:
        if isinstance(m, nn.Linear):
            linears.append(m)
            acts.append(False)
            return True
        if isinstance(m, nn.Flatten):
            return not linears  # only at the input
        if isinstance(m, nn.Tanh | nn.ReLU | nn.ELU):
            if not acts or acts[-1]:
                return False
            acts[-1] = True
            return True
        if isinstance(m, MLP | nn.Sequential):
            return all(walk(c) for c in m)
        return False

    if not all(walk(m) for m in modules) or not linears:
        return None
    if not all(acts[:-1]) or acts[-1]:
        return None
    return linears


def _activation(h: torch.Tensor, act: str) -> torch.Tensor:
    """act(h), in place on ``h`` (a fresh tensor of the forward pass)."""
    if act == "tanh":
        if h.device.type == "cpu" and h.is_contiguous():
            a = h.numpy()
            np.tanh(a, out=a)
            return h
        return torch.tanh(h)
    if act == "relu":
        return torch.relu_(h)
    if act == "elu":
        return nn.functional.elu(h)
    raise InvalidArgumentError(f"activation must be tanh, relu or elu; got {act!r}")


def activation_backward(grad: torch.Tensor, h: torch.Tensor, act: str) -> torch.Tensor:
    """dL/dz from dL/dh and the activation's output h = act(z)."""
    aten = torch.ops.aten
    if act == "tanh":
        return aten.tanh_backward(grad, h)  # type: ignore[no-any-return]
    if act == "relu":
        return aten.threshold_backward(grad, h, 0)  # type: ignore[no-any-return]
    return aten.elu_backward(grad, 1.0, 1.0, 1.0, True, h)  # type: ignore[no-any-return]


def mlp_forward(
    layers: Sequence[nn.Linear], act: str, x: torch.Tensor
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """The MLP's output and every layer's input (what :func:`mlp_backward` needs).

    Runs without building an autograd graph. Returns ``(out, inputs)`` with
    ``inputs[l]`` the input h_{l} of layer l (``inputs[0]`` is ``x`` flattened).
    """
    with torch.no_grad():
        h = x.reshape(len(x), -1)
        inputs = []
        last = len(layers) - 1
        for i, layer in enumerate(layers):
            inputs.append(h)
            h = _affine(h, layer.weight, layer.bias)
            if i < last:
                h = _activation(h, act)
    return h, inputs


def _affine(h: torch.Tensor, w: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The affine map z = h W^T + b, in the orientation BLAS runs fastest.

    A layer with a few outputs (a Q-head over 2-4 actions, a policy head) on a batch
    runs about twice as fast as (W h^T + b)^T than as h W^T + b (a (128, 256) batch
    into 3 outputs: 6.5 us against 14 us; 5,000 rows: 190 us against 390 us); the
    result is made contiguous again.
    """
    if 1 < w.shape[0] <= 4 and len(h) >= 32:
        return torch.addmm(b.unsqueeze(1), w, h.t()).t().contiguous()
    return torch.addmm(b, h, w.t())


class NumpyMLP:
    """An MLP's forward pass in NumPy, for acting on a few observations at a time.

    The same equations as :func:`mlp_forward` (h_l = act(h_{l-1} W_l^T + b_l), no act
    on the last layer), on NumPy views of the parameters' memory, so every optimizer
    step is seen without a copy. For one to a few dozen observations the arithmetic
    takes a few microseconds and torch's per-operation dispatch costs more than it
    (a 4-256-256-2 Q-network on one observation: about 10 us against 30 us); NumPy's
    BLAS may round the products differently in the last place.

    Args:
        layers: The MLP's Linear layers, as :func:`mlp_layers` gives them.
        act: Activation name (tanh, relu or elu).
    """

    def __init__(self, layers: Sequence[nn.Linear], act: str) -> None:
        if act not in ("tanh", "relu", "elu"):
            raise InvalidArgumentError(f"activation must be tanh, relu or elu; got {act!r}")
        self.act = act
        self.params = [(layer.weight, layer.bias) for layer in layers]
        self._views: list[tuple[Any, Any]] = []
        self._ptrs: list[int] = []

    def _arrays(self) -> list[tuple[Any, Any]]:
        """NumPy views of the weights and biases (made again if their memory moved)."""
        ptrs = [w.data_ptr() for w, _ in self.params]
        if ptrs != self._ptrs:
            self._views = [(w.detach().numpy().T, b.detach().numpy()) for w, b in self.params]
            self._ptrs = ptrs
        return self._views

    def __call__(self, x: Any) -> Any:
        """The MLP's output for a batch ``x`` (a NumPy array, first axis the batch)."""
        views = self._arrays()
        h = np.asarray(x, dtype=np.float32).reshape(len(x), self.params[0][0].shape[1])
        last = len(views) - 1
        for i, (w_t, b) in enumerate(views):
            h = h @ w_t
            h += b
            if i < last:
                if self.act == "relu":
                    np.maximum(h, 0.0, out=h)
                elif self.act == "tanh":
                    np.tanh(h, out=h)
                else:  # elu: exp(h) - 1 where h <= 0
                    np.putmask(h, h <= 0, np.expm1(np.minimum(h, 0.0)))
        return h


def _weight_grad(g: torch.Tensor, h: torch.Tensor, out: torch.Tensor) -> None:
    """Write dW = g^T h into ``out``, in the orientation BLAS runs fastest.

    A product with few rows and many columns runs several times faster than its
    transpose for these shapes (a (64, 4) first-layer gradient: 28 us as g^T h, 4 us
    as (h^T g)^T), so the narrow side goes first.
    """
    if h.shape[1] < g.shape[1]:
        out.copy_(torch.mm(h.t(), g).t())
    else:
        torch.mm(g.t(), h, out=out)


def mlp_backward(
    layers: Sequence[nn.Linear], act: str, inputs: Sequence[torch.Tensor], grad_out: torch.Tensor
) -> None:
    """Set the ``.grad`` of every weight and bias of the MLP to dL/dtheta.

    A parameter that already has a ``.grad`` gets it overwritten in place (so gradients
    can live in one flat buffer, see :class:`FlatParameters`); one without gets a new
    tensor.

    Args:
        layers: The MLP's Linear layers, as :func:`mlp_layers` gives them.
        act: Activation name.
        inputs: Every layer's input, from :func:`mlp_forward`.
        grad_out: (B, out) dL/d(output).
    """
    with torch.no_grad():
        g = grad_out
        for i in range(len(layers) - 1, -1, -1):
            layer, h = layers[i], inputs[i]
            w, b = layer.weight, layer.bias
            if b.grad is None:
                b.grad = torch.empty_like(b)
            if w.grad is None:
                w.grad = torch.empty_like(w)
            torch.sum(g, 0, out=b.grad)
            _weight_grad(g, h, w.grad)
            if i > 0:
                g = activation_backward(torch.mm(g, w), h, act)


class FlatParameters:
    """The parameters of a network as views of one flat tensor, and their gradients too.

    An optimizer step and a gradient-norm clip then act on one tensor instead of one
    per layer (the same elementwise arithmetic: Adam's update is per element, and the
    norm is the same sum of squares, summed in another order), which saves most of
    their per-tensor overhead for small networks. The parameters stay what they were
    (the same objects, names and shapes in ``state_dict``); only their storage moves.

    Args:
        params: The parameters; each must be a leaf tensor of float dtype.
    """

    def __init__(self, params: Sequence[torch.Tensor]) -> None:
        self.params = list(params)
        sizes = [p.numel() for p in self.params]
        dtype = self.params[0].dtype
        data = torch.cat([p.detach().reshape(-1).to(dtype) for p in self.params])
        self.flat = nn.Parameter(data)
        self.flat.grad = torch.zeros_like(data)
        offset = 0
        self.offsets: list[int] = []  # where each parameter starts in the buffer
        for p, n in zip(self.params, sizes, strict=True):
            self.offsets.append(offset)
            p.data = data[offset : offset + n].view_as(p)
            p.grad = self.flat.grad[offset : offset + n].view_as(p)
            offset += n

    def clip_grad_norm_(self, max_norm: float) -> torch.Tensor:
        """Scale the flat gradient so that its L2 norm is at most ``max_norm``.

        g <- g * min(1, max_norm / (||g||_2 + 1e-6)), the arithmetic of
        :func:`~policylab.deep.common.networks.clip_grad_norm` on the one tensor (the
        same numbers), without its per-call list handling. The factor is computed from
        the norm read back as a Python number, in float32 as torch computes it (the sum,
        the reciprocal, the product and the minimum, each rounded to float32), and the
        multiplication is skipped where the factor is exactly 1. Returns the norm before
        clipping as a 0-d tensor.
        """
        grad = self.flat.grad
        assert grad is not None
        norm = torch._foreach_norm([grad])[0]
        f32 = np.float32
        coef = f32(1.0) / (f32(float(norm)) + f32(1e-6)) * f32(max_norm)
        if coef < 1.0:
            grad.mul_(float(coef))
        return norm

    def state_from_per_parameter(
        self, state: dict[str, Any], order: Sequence[torch.Tensor] | None = None
    ) -> dict[str, Any]:
        """An optimizer ``state_dict`` with one entry per parameter, made flat.

        Checkpoints written before parameters were flattened keep Adam's moments per
        parameter; this concatenates them in the buffer's order so that the flat
        optimizer resumes exactly where the old one stopped. A state that already is
        flat comes back unchanged.

        Args:
            state: The per-parameter optimizer state.
            order: The parameters in the order the old optimizer listed them (default:
                the buffer's order).
        """
        groups = state.get("param_groups", [])
        ids = [i for g in groups for i in g.get("params", [])]
        old_order = list(order) if order is not None else self.params
        if len(ids) == 1 or len(ids) != len(self.params) or len(old_order) != len(ids):
            return state
        slot = {id(p): i for p, i in zip(old_order, ids, strict=True)}
        per = state.get("state", {})
        flat_state: dict[str, Any] = {}
        if per:
            first = per[slot[id(self.params[0])]]
            for key, value in first.items():
                if isinstance(value, torch.Tensor) and value.shape == self.params[0].shape:
                    parts = [per[slot[id(p)]][key].reshape(-1) for p in self.params]
                    flat_state[key] = torch.cat(parts)
                else:
                    flat_state[key] = value
        group = dict(groups[0])
        group["params"] = [0]
        return {"state": {0: flat_state} if flat_state else {}, "param_groups": [group]}


@torch.no_grad()
def fused_adam_step(optimizer: torch.optim.Optimizer) -> None:
    """``optimizer.step()`` for a fused Adam, minus its wrapper.

    ``torch.optim.Adam.step`` spends tens of microseconds in Python (hooks, profiling
    labels, grouping the tensors by device and dtype, argument checks) around one fused
    kernel that updates a 70k-parameter network in about as long. This calls that kernel
    (``torch._fused_adam_``) directly with the optimizer's own state, group by group, so
    the numbers are bit for bit those of ``optimizer.step()`` and the optimizer's
    ``state_dict`` stays what it is. Anything else (a first step, which creates the
    state; AMSGrad, maximize or decoupled weight decay; a non-fused or non-Adam
    optimizer; a tensor learning rate) falls back to ``optimizer.step()``.

    Args:
        optimizer: The optimizer to step.
    """
    groups = optimizer.param_groups
    if type(optimizer) is not torch.optim.Adam or not all(
        g.get("fused")
        and not g.get("amsgrad")
        and not g.get("maximize")
        and not g.get("decoupled_weight_decay")
        and not isinstance(g["lr"], torch.Tensor)
        for g in groups
    ):
        optimizer.step()
        return
    state = optimizer.state
    todo = []
    for g in groups:
        params = [p for p in g["params"] if p.grad is not None]
        if not all(p in state and "exp_avg" in state[p] for p in params):
            optimizer.step()
            return
        todo.append((g, params))
    for g, params in todo:
        if not params:
            continue
        st = [state[p] for p in params]
        steps = [s["step"] for s in st]
        torch._foreach_add_(steps, 1)
        beta1, beta2 = g["betas"]
        torch._fused_adam_(
            params, [p.grad for p in params], [s["exp_avg"] for s in st],
            [s["exp_avg_sq"] for s in st], [], steps,
            amsgrad=False, lr=g["lr"], beta1=beta1, beta2=beta2,
            weight_decay=g["weight_decay"], eps=g["eps"], maximize=False,
            grad_scale=None, found_inf=None,
        )  # fmt: skip
