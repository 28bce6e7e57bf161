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
    "ChainPasses",
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
    """act(h), in place on ``h`` (a tensor of the forward pass, possibly a strided view)."""
    if act == "tanh":
        if h.device.type == "cpu":
            a = h.numpy()
            np.tanh(a, out=a)
            return h
        return torch.tanh_(h)
    if act == "relu":
        return torch.relu_(h)
    if act == "elu":
        return nn.functional.elu_(h)
    raise InvalidArgumentError(f"activation must be tanh, relu or elu; got {act!r}")


def activation_backward(
    grad: torch.Tensor, h: torch.Tensor, act: str, out: torch.Tensor | None = None
) -> torch.Tensor:
    """dL/dz from dL/dh and the activation's output h = act(z).

    tanh: dL/dz = dL/dh (1 - h^2); ReLU: dL/dh [h > 0]; ELU: dL/dh (h + 1) where
    h <= 0, else dL/dh. With ``out`` (which may be ``grad`` itself: the map is
    elementwise) the result is written there instead of a new tensor.
    """
    aten = torch.ops.aten
    if out is None:
        if act == "tanh":
            return aten.tanh_backward(grad, h)  # type: ignore[no-any-return]
        if act == "relu":
            return aten.threshold_backward(grad, h, 0)  # type: ignore[no-any-return]
        return aten.elu_backward(grad, 1.0, 1.0, 1.0, True, h)  # type: ignore[no-any-return]
    if act == "tanh":
        return aten.tanh_backward.grad_input(grad, h, grad_input=out)  # type: ignore[no-any-return]
    if act == "relu":
        return aten.threshold_backward.grad_input(grad, h, 0, grad_input=out)  # type: ignore[no-any-return]
    return aten.elu_backward.grad_input(grad, 1.0, 1.0, 1.0, True, h, grad_input=out)  # type: ignore[no-any-return]


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


def _block_grad(h: torch.Tensor, g: torch.Tensor, out: torch.Tensor) -> None:
    """Write [dW^T; db] = [h, 1]^T dz into ``out``, the narrow orientation first.

    For a layer with a few outputs (a Q-head over 2-4 actions) dz^T [h, 1] into a
    (out, in + 1) product, transposed into place, costs about 7.6 us where the
    (in + 1, out) product costs 12.5 (a (128, 257) input, 3 outputs).
    """
    if 4 * g.shape[1] <= h.shape[1]:
        out.copy_(torch.mm(g.t(), h).t())
    else:
        torch.mm(h.t(), g, out=out)


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

    By default the buffer holds the parameters one after the other. With ``chain``
    (the Linear layers of a plain MLP, whose weights and biases ``params`` lists in
    order) it holds each layer as one (in + 1, out) block [W^T; b]: the weight is a
    transposed view of the block's first rows and the bias its last row, so that
    :class:`ChainPasses` computes z = [h, 1] [W^T; b] and the weight and bias
    gradients [h, 1]^T dz each in one matrix product.

    Args:
        params: The parameters; each must be a leaf tensor of float dtype.
        chain: The Linear layers behind ``params``, for the block layout.

    Raises:
        InvalidArgumentError: If ``chain`` is given and ``params`` are not its layers'
            weights and biases in order.
    """

    def __init__(
        self, params: Sequence[torch.Tensor], chain: Sequence[nn.Linear] | None = None
    ) -> None:
        self.params = list(params)
        self.chain = list(chain) if chain is not None else None
        if self.chain is not None:
            expected = [p for layer in self.chain for p in (layer.weight, layer.bias)]
            if len(expected) != len(self.params) or any(
                a is not b for a, b in zip(expected, self.params, strict=False)
            ):
                raise InvalidArgumentError(
                    "FlatParameters: params must be the chain's weights and biases, in order"
                )
        sizes = [p.numel() for p in self.params]
        self.offsets: list[int] = []  # where each parameter starts in the concatenation
        offset = 0
        for n in sizes:
            self.offsets.append(offset)
            offset += n
        data = self.from_parameters([p.detach() for p in self.params])
        self.flat = nn.Parameter(data)
        self.flat.grad = torch.zeros_like(data)
        for i, p in enumerate(self.params):
            p.data = self.view(data, i)
            p.grad = self.view(self.flat.grad, i)

    def blocks(self, v: torch.Tensor) -> list[torch.Tensor]:
        """The (in + 1, out) blocks [W^T; b] of each layer in a flat tensor ``v``."""
        assert self.chain is not None
        out, offset = [], 0
        for layer in self.chain:
            n_out, n_in = layer.weight.shape
            out.append(v[offset : offset + (n_in + 1) * n_out].view(n_in + 1, n_out))
            offset += (n_in + 1) * n_out
        return out

    def view(self, v: torch.Tensor, i: int) -> torch.Tensor:
        """Parameter ``i``'s view of a flat tensor ``v`` laid out as the buffer."""
        p = self.params[i]
        if self.chain is None:
            return v[self.offsets[i] : self.offsets[i] + p.numel()].view(p.shape)
        block = self.blocks(v)[i // 2]
        return block[:-1].t() if i % 2 == 0 else block[-1]

    def from_parameters(self, tensors: Sequence[torch.Tensor]) -> torch.Tensor:
        """A flat tensor laid out as the buffer, holding one tensor per parameter."""
        dtype = self.params[0].dtype
        out = torch.empty(sum(p.numel() for p in self.params), dtype=dtype)
        for i, (p, t) in enumerate(zip(self.params, tensors, strict=True)):
            self.view(out, i).copy_(t.reshape(p.shape))
        return out

    def concatenated(self, v: torch.Tensor) -> torch.Tensor:
        """A flat tensor ``v`` laid out as the buffer, as the parameters one after the other."""
        return torch.cat([self.view(v, i).reshape(-1) for i in range(len(self.params))])

    def _from_concatenated(self, v: torch.Tensor) -> torch.Tensor:
        """Inverse of :meth:`concatenated`."""
        return self.from_parameters(
            [v[o : o + p.numel()] for o, p in zip(self.offsets, self.params, strict=True)]
        )

    def state_for_checkpoint(self, state: dict[str, Any]) -> dict[str, Any]:
        """The flat optimizer's ``state_dict`` with its moments in concatenated order.

        Checkpoints store the moments as the parameters one after the other, whatever
        the buffer's layout; :meth:`state_from_per_parameter` reads them back.
        """
        return self._relayout(state, self.concatenated)

    def _relayout(self, state: dict[str, Any], fn: Any) -> dict[str, Any]:
        if self.chain is None:
            return state
        n = self.flat.numel()
        per = {
            k: {
                key: fn(v) if isinstance(v, torch.Tensor) and v.numel() == n else v
                for key, v in st.items()
            }
            for k, st in state.get("state", {}).items()
        }
        return {**state, "state": per}

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
        norm: torch.Tensor = torch.linalg.vector_norm(grad)  # _foreach_norm runs this per tensor
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
        flat (the parameters one after the other, as checkpoints store it) is laid out
        as the buffer (for the default layout: unchanged).

        Args:
            state: The per-parameter optimizer state.
            order: The parameters in the order the old optimizer listed them (default:
                the buffer's order).
        """
        groups = state.get("param_groups", [])
        ids = [i for g in groups for i in g.get("params", [])]
        old_order = list(order) if order is not None else self.params
        if len(ids) == 1:  # already flat: the parameters one after the other
            return self._relayout(state, self._from_concatenated)
        if len(ids) != len(self.params) or len(old_order) != len(ids):
            return state
        slot = {id(p): i for p, i in zip(old_order, ids, strict=True)}
        per = state.get("state", {})
        flat_state: dict[str, Any] = {}
        if per:
            first = per[slot[id(self.params[0])]]
            for key, value in first.items():
                if isinstance(value, torch.Tensor) and value.shape == self.params[0].shape:
                    parts = [per[slot[id(p)]][key] for p in self.params]
                    flat_state[key] = self.from_parameters(parts)
                else:
                    flat_state[key] = value
        group = dict(groups[0])
        group["params"] = [0]
        return {"state": {0: flat_state} if flat_state else {}, "param_groups": [group]}


class ChainPasses:
    """Forward and backward passes of a plain MLP held as [W^T; b] blocks, one product each.

    The equations of :func:`mlp_forward` and :func:`mlp_backward`, with each layer's
    input extended by a column of ones, h^+ = [h, 1], and its parameters stored as one
    (in + 1, out) block [W^T; b] (:class:`FlatParameters` with ``chain``):

        forward:   z_l = h^+_{l-1} [W_l^T; b_l],   h_l = act(z_l)   (no act on the last)
        backward:  [dW_l^T; db_l] = (h^+_{l-1})^T dz_l,
                   dz_{l-1} = (dz_l W_l) * act'(z_{l-1})

    so the bias is added inside the product and its gradient (the column sums of dz_l)
    comes out of the weight gradient's product as its last row: one matrix product per
    layer and pass instead of a product, a bias broadcast and a column sum, and every
    product in the orientation the row-major blocks give. The layers' inputs live in
    buffers kept between calls (one set per batch size), so a gradient step allocates
    nothing but its output. The sums run in another order than with a separate bias,
    so results agree with :func:`mlp_forward` to float rounding.

    Args:
        flat: The network's parameters in the block layout (``FlatParameters(...,
            chain=layers)``); the gradients are written into ``flat.flat.grad``.
        act: Activation name (tanh, relu or elu).
    """

    def __init__(self, flat: FlatParameters, act: str) -> None:
        if flat.chain is None:
            raise InvalidArgumentError("ChainPasses needs FlatParameters made with chain=")
        if act not in ("tanh", "relu", "elu"):
            raise InvalidArgumentError(f"activation must be tanh, relu or elu; got {act!r}")
        assert flat.flat.grad is not None
        self.act = act
        self.weights = flat.blocks(flat.flat.detach())
        self.grads = flat.blocks(flat.flat.grad)
        self._buffers: dict[int, tuple[list[torch.Tensor], list[torch.Tensor]]] = {}
        self._last: tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor]] | None = None

    def with_ones(self, x: torch.Tensor) -> torch.Tensor:
        """[x, 1]: a batch of inputs (flattened) with a column of ones appended."""
        x = x.reshape(len(x), -1)
        return torch.cat([x, torch.ones(len(x), 1, dtype=x.dtype)], dim=1)

    def _layer_buffers(self, batch: int) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        """Per hidden layer: its output [h, 1] (ones in the last column) and dL/dz."""
        if batch not in self._buffers:
            widths, dtype = [w.shape[1] for w in self.weights[:-1]], self.weights[0].dtype
            outs = [torch.ones(batch, n + 1, dtype=dtype) for n in widths]
            grads = [torch.empty(batch, n, dtype=dtype) for n in widths]
            self._buffers[batch] = (outs, grads)
        return self._buffers[batch]

    @torch.no_grad()
    def forward(self, x_ones: torch.Tensor) -> torch.Tensor:
        """The network's output for inputs [x, 1] (:meth:`with_ones`).

        Keeps what :meth:`backward` needs, until the next call.
        """
        outs, grads = self._layer_buffers(len(x_ones))
        h = x_ones
        for block, out in zip(self.weights[:-1], outs, strict=True):
            _activation(torch.mm(h, block, out=out[:, :-1]), self.act)
            h = out
        self._last = (x_ones, outs, grads)
        return torch.mm(h, self.weights[-1])

    @torch.no_grad()
    def backward(self, grad_out: torch.Tensor) -> None:
        """Write dL/dtheta of the last :meth:`forward`'s batch into the flat gradient.

        Args:
            grad_out: (B, out) dL/d(output).
        """
        assert self._last is not None, "backward needs a forward pass first"
        x_ones, outs, grads = self._last
        inputs = [x_ones, *outs]
        g = grad_out
        for i in range(len(self.weights) - 1, -1, -1):
            _block_grad(inputs[i], g, self.grads[i])
            if i > 0:
                dh = torch.mm(g, self.weights[i][:-1].t(), out=grads[i - 1])
                g = activation_backward(dh, outs[i - 1][:, :-1], self.act, out=dh)


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
        for step in steps:  # one add_ each: _foreach_add_ costs more for a few tensors
            step.add_(1)
        beta1, beta2 = g["betas"]
        torch._fused_adam_(
            params, [p.grad for p in params], [s["exp_avg"] for s in st],
            [s["exp_avg_sq"] for s in st], [], steps,
            amsgrad=False, lr=g["lr"], beta1=beta1, beta2=beta2,
            weight_decay=g["weight_decay"], eps=g["eps"], maximize=False,
            grad_scale=None, found_inf=None,
        )  # fmt: skip
