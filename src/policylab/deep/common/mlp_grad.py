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

:class:`ChainPasses` is the one implementation of these passes, used by every learner
(DQN's Q-network, PPO's actor and critic, the SAC and TD3 actors); it runs each layer as
one product on its parameters held as a [W^T; b] block (:class:`FlatParameters` with
``chain``). :func:`mlp_layers` finds such a chain in a module; networks it does not
recognise (convolutions, one-hot inputs) keep autograd. :class:`NumpyMLP` is the forward
pass in NumPy, for acting on a few observations.
"""

from __future__ import annotations

import weakref
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
    "Part",
    "activation_backward",
    "as_one_tensor",
    "fused_adam_step",
    "linear_parts",
    "match_state_layout",
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


class NumpyMLP:
    """An MLP's forward pass in NumPy, for acting on a few observations at a time.

    The same equations as :class:`ChainPasses` (h_l = act(h_{l-1} W_l^T + b_l), no act
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


Part = tuple[torch.Tensor, bool]
"""A parameter that is part of a layer's [W^T; b] block, and whether it is held there
transposed (an ``nn.Linear`` weight, (out, in), is the block's rows W^T)."""


def linear_parts(layers: Sequence[nn.Linear]) -> list[list[Part]]:
    """Each Linear layer's parameters as parts of its block [W^T; b]: W transposed, b."""
    return [[(layer.weight, True), (layer.bias, False)] for layer in layers]


def _rows(p: torch.Tensor, transposed: bool) -> torch.Tensor:
    """The rows a parameter takes in its block: W^T, a bias as one row, or as it is."""
    if transposed:
        return p.mT
    return p[None] if p.dim() == 1 else p


def _block_of(rows: Sequence[torch.Tensor]) -> torch.Tensor | None:
    """The block [R_1; R_2; ...] (stacked along the second-to-last axis) ``rows`` are views of.

    A block of one network is (n, out), row-major; k stacked networks' blocks (k, n,
    out) lie in memory as (n, k, out), row j of every network together, so that each
    part (a (k, rows, out) parameter) is one stretch of memory. None where ``rows`` are
    not laid out so, one after the other in one tensor's memory.
    """
    first = rows[0]
    stack, n_out = first.shape[:-2], first.shape[-1]
    row = n_out * (stack[0] if stack else 1)  # the memory one row of the block takes
    stride = (n_out, row, 1) if stack else (row, 1)
    storage, start, offset = first.untyped_storage().data_ptr(), first.storage_offset(), 0
    for r in rows:
        if (
            r.dtype != first.dtype
            or r.shape[:-2] != stack
            or r.shape[-1] != n_out
            or r.untyped_storage().data_ptr() != storage
            or r.storage_offset() != start + offset * row
            or any(
                a != b for a, b, size in zip(r.stride(), stride, r.shape, strict=True) if size > 1
            )
        ):
            return None
        offset += r.shape[-2]
    return first.as_strided((*stack, offset, n_out), stride)


def _mm(a: torch.Tensor, b: torch.Tensor, out: torch.Tensor | None = None) -> torch.Tensor:
    """The product a b, or one per stacked network (a 2-d operand is shared by all).

    Two shapes go through other kernels than a plain product, because the plain one is
    several times slower on them (a one-output layer, a Q-head over a few actions, the
    few action columns of dL/dx, the backward step through a one-output layer):

    - an outer product (a has one column) is one multiplication per element, so it is
      computed as that, a broadcast product, bit for bit what the product gives: a
      (2, 256, 1) x (2, 1, 257) product took 310 us as a batched product and 37 us so;
    - a narrow result (at most 8 columns, at least 4 rows per column, and a of at
      least 16,384 entries, below which the copies cost more than they save) is computed
      as the wide one, c = (b^T a^T)^T: (256, 257) x (257, 6) took 184 us and 45 us so,
      (2, 256, 257) x (2, 257, 1) 451 us and 28 us (single products on one core of an
      AMD EPYC with torch's MKL; the narrow orientation was faster on an Intel core
      too). The sums run in another order, so c agrees with a b to float rounding. A
      single matrix-vector product (2-d, one column) is left to the plain product,
      which runs it as one already.
    """
    if a.shape[-1] == 1:
        return torch.mul(a, b.contiguous(), out=out)
    n = b.shape[-1]
    rows, inner = a.shape[-2:]
    wide = rows >= 4 * n and rows * inner >= 16_384  # smaller: the copies cost more
    if n <= 8 and wide and (n > 1 or a.dim() == 3 or b.dim() == 3):
        bt = b.mT.contiguous() if n == 1 else b.mT
        c = _mm(bt, a.mT).mT  # laid out row-major again: a copy of a few columns
        return c.contiguous() if out is None else out.copy_(c)
    if a.dim() == 2 and b.dim() == 2:
        return torch.mm(a, b, out=out)
    if a.dim() == 2:
        a = a.expand(len(b), -1, -1)
    elif b.dim() == 2:
        b = b.expand(len(a), -1, -1)
    return torch.bmm(a, b, out=out)


class FlatParameters:
    """The parameters of a network as views of one flat tensor, and their gradients too.

    An optimizer step and a gradient-norm clip then act on one tensor instead of one
    per layer (the same elementwise arithmetic: Adam's update is per element, and the
    norm is the same sum of squares, summed in another order), which saves most of
    their per-tensor overhead for small networks. The parameters stay what they were
    (the same objects, names and shapes in ``state_dict``); only their storage moves.

    By default the buffer holds the parameters one after the other. With ``chain``
    (Linear layers whose weight and bias ``params`` lists one right after the other:
    the layers of one or several plain MLPs) it holds each of those layers as one
    (in + 1, out) block [W^T; b] in the place of its weight and bias: the weight is a
    transposed view of the block's first rows and the bias its last row, so that
    :class:`ChainPasses` computes z = [h, 1] [W^T; b] and the weight and bias
    gradients [h, 1]^T dz each in one matrix product. Other parameters (a log std)
    keep the default layout.

    Args:
        params: The parameters; each must be a leaf tensor of float dtype.
        chain: The Linear layers to hold as [W^T; b] blocks.

    Raises:
        InvalidArgumentError: If a layer of ``chain`` does not have its weight and then
            its bias among ``params``.
    """

    def __init__(
        self, params: Sequence[torch.Tensor], chain: Sequence[nn.Linear] | None = None
    ) -> None:
        self.params = list(params)
        self.chain = list(chain) if chain is not None else None
        self.offsets: list[int] = []  # where each parameter starts in the concatenation
        offset = 0
        for p in self.params:
            self.offsets.append(offset)
            offset += p.numel()
        index = {id(p): i for i, p in enumerate(self.params)}
        self._layer_of: dict[int, int] = {}  # parameter index -> its layer in chain
        self._block_start: list[int] = []  # per layer: where its block starts
        for j, layer in enumerate(self.chain or ()):
            i = index.get(id(layer.weight), -1)
            if i < 0 or i + 1 == len(self.params) or self.params[i + 1] is not layer.bias:
                raise InvalidArgumentError(
                    "FlatParameters: params must hold each of the chain's weights and biases, "
                    f"the bias right after its weight (layer {j} of the chain)"
                )
            self._layer_of[i] = self._layer_of[i + 1] = j
            # the block takes the place of the weight and the bias: (in + 1) out elements
            self._block_start.append(self.offsets[i])
        data = self.from_parameters([p.detach() for p in self.params])
        self.flat = nn.Parameter(data)
        self.flat.grad = torch.zeros_like(data)
        for i, p in enumerate(self.params):
            p.data = self.view(data, i)
            p.grad = self.view(self.flat.grad, i)

    @classmethod
    def of_chain(cls, chain: Sequence[nn.Linear]) -> FlatParameters:
        """The weights and biases of a plain MLP's Linear layers, each layer as one block."""
        return cls([p for layer in chain for p in (layer.weight, layer.bias)], chain)

    def _block(self, v: torch.Tensor, j: int) -> torch.Tensor:
        """Layer ``j``'s (in + 1, out) block [W^T; b] in a flat tensor ``v``."""
        assert self.chain is not None
        n_out, n_in = self.chain[j].weight.shape
        start = self._block_start[j]
        return v[start : start + (n_in + 1) * n_out].view(n_in + 1, n_out)

    def blocks(self, v: torch.Tensor) -> list[torch.Tensor]:
        """The (in + 1, out) blocks [W^T; b] of each layer of ``chain`` in a flat tensor ``v``."""
        return [self._block(v, j) for j in range(len(self.chain or ()))]

    def view(self, v: torch.Tensor, i: int) -> torch.Tensor:
        """Parameter ``i``'s view of a flat tensor ``v`` laid out as the buffer."""
        p = self.params[i]
        j = self._layer_of.get(i)
        if j is None:
            return v[self.offsets[i] : self.offsets[i] + p.numel()].view(p.shape)
        block = self._block(v, j)
        return block[:-1].t() if p is self.chain[j].weight else block[-1]  # type: ignore[index]

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

    The equations of backpropagation through the MLP (see the module's docstring), with
    each layer's input extended by a column of ones, h^+ = [h, 1], and its parameters
    stored as one (in + 1, out) block [W^T; b] (:class:`FlatParameters` with ``chain``):

        forward:   z_l = h^+_{l-1} [W_l^T; b_l],   h_l = act(z_l)   (no act on the last)
        backward:  [dW_l^T; db_l] = (h^+_{l-1})^T dz_l,
                   dz_{l-1} = (dz_l W_l) * act'(z_{l-1}),   dL/dx = dz_1 W_1

    so the bias is added inside the product and its gradient (the column sums of dz_l)
    comes out of the weight gradient's product as its last row: one matrix product per
    layer and pass instead of a product, a bias broadcast and a column sum, and every
    product in the orientation the row-major blocks give. The layers' inputs live in
    buffers kept between calls (one set per batch size), so a gradient step allocates
    nothing but its output. The sums run in another order than with a separate bias,
    so results agree with autograd's to float rounding.

    Several MLPs of the same shape can be stacked (k, in + 1, out) blocks, such as the
    twin critics of SAC and TD3: every product is then one batched product over the k
    networks, which share the input x and have outputs (k, B, out).

    The blocks are found from the parameters at each call, so the passes follow
    parameters that move (a flat buffer made later, ``.double()``). A layer whose
    parameters are not views of one block still works: its block is copied for each
    forward pass, and its gradients copied into ``.grad`` after each backward one. A
    layer whose parameters have no ``.grad`` gets one laid out as a block.

    Args:
        layers: The MLP's Linear layers (:func:`mlp_layers`), a :class:`FlatParameters`
            made with ``chain=`` those layers, or each layer's block as its parts (the
            parameters in the block's order, see :func:`linear_parts`).
        act: Activation name (tanh, relu or elu).
    """

    def __init__(
        self,
        layers: FlatParameters | Sequence[nn.Linear] | Sequence[Sequence[Part]],
        act: str,
    ) -> None:
        if isinstance(layers, FlatParameters):
            if layers.chain is None:
                raise InvalidArgumentError("ChainPasses needs FlatParameters made with chain=")
            layers = layers.chain
        if act not in ("tanh", "relu", "elu"):
            raise InvalidArgumentError(f"activation must be tanh, relu or elu; got {act!r}")
        self.act = act
        self.parts: list[list[Part]] = [
            linear_parts([layer])[0] if isinstance(layer, nn.Linear) else list(layer)
            for layer in layers
        ]
        self._firsts = [layer[0][0] for layer in self.parts]  # moved with their layer
        self._weights: tuple[list[int], list[torch.Tensor | None], bool] = ([], [], False)
        self._grads: tuple[list[int], list[torch.Tensor | None]] = ([], [])
        self._buffers: dict[tuple[Any, ...], tuple[list[torch.Tensor], ...]] = {}
        self._scratch: dict[tuple[Any, ...], tuple[list[torch.Tensor], ...]] = {}
        self._last: tuple[torch.Tensor, list[torch.Tensor], list[torch.Tensor]] | None = None
        self._last_weights: list[torch.Tensor] = []
        self._last_first: int | None = None

    @staticmethod
    def with_ones(*x: torch.Tensor) -> torch.Tensor:
        """[x, 1]: a batch of inputs (flattened; several side by side) and a column of ones."""
        cols = [t.reshape(len(t), -1) for t in x]
        if len(cols) == 1:
            return torch.constant_pad_nd(cols[0], (0, 1), 1.0)
        return torch.cat([*cols, torch.ones(len(cols[0]), 1, dtype=cols[0].dtype)], dim=1)

    def _weight_blocks(self) -> list[torch.Tensor]:
        """Each layer's block: a view of its parameters where they are laid out so.

        Found again when the memory of a layer's first parameter moved (parameters move
        together: into a flat buffer, by ``.double()``).
        """
        ptrs = [p.data_ptr() for p in self._firsts]
        if ptrs != self._weights[0]:
            views = [_block_of([_rows(p.detach(), t) for p, t in layer]) for layer in self.parts]
            self._weights = (ptrs, views, all(v is not None for v in views))
        if self._weights[2]:
            return self._weights[1]  # type: ignore[return-value]
        return [
            torch.cat([_rows(p.detach(), t) for p, t in layer], -2) if v is None else v
            for layer, v in zip(self.parts, self._weights[1], strict=True)
        ]

    def _grad_blocks(self) -> list[torch.Tensor | None]:
        """Each layer's gradient block where its parameters' ``.grad`` is laid out so."""
        ptrs = [0 if p.grad is None else p.grad.data_ptr() for p in self._firsts]
        if ptrs != self._grads[0]:
            views: list[torch.Tensor | None] = []
            for layer in self.parts:
                grads = [p.grad for p, _ in layer]
                views.append(
                    None
                    if any(g is None for g in grads)
                    else _block_of([_rows(g, t) for g, (_, t) in zip(grads, layer, strict=True)])  # type: ignore[arg-type]
                )
            self._grads = (ptrs, views)
        return self._grads[1]

    def _set_grads(self, i: int, block: torch.Tensor) -> None:
        """Give layer ``i``'s parameters their gradients from its gradient block.

        A parameter without ``.grad`` gets a view of ``block`` where the parameters are
        views of a block themselves (a gradient then lies in memory as its parameter,
        which a fused optimizer needs), else a copy laid out as the parameter; one with
        a ``.grad`` gets it overwritten.
        """
        start, views = 0, self._weights[1][i] is not None
        for p, transposed in self.parts[i]:
            rows = _rows(p, transposed).shape[-2]
            value = block[..., start : start + rows, :]
            if transposed:
                value = value.mT
            elif value.shape != p.shape:  # a bias (out,) from its row (1, out)
                value = value[0]
            if p.grad is not None:
                p.grad.copy_(value)
            else:
                p.grad = value if views else torch.empty_like(p).copy_(value)
            start += rows

    def _layer_buffers(
        self, batch: int, dtype: torch.dtype, stack: tuple[int, ...], keep: bool
    ) -> tuple[list[torch.Tensor], ...]:
        """Per hidden layer: its output [h, 1] (ones in the last column) and [dL/dz, *].

        Kept between calls: for the passes of a gradient step one set per batch size,
        for a forward pass alone (whose batch sizes may vary from call to call) the
        outputs of the last size only. ``stack`` is (k,) for k stacked networks, else ().
        """
        key = (batch, dtype, *stack)
        have = self._buffers.get(key) if keep else self._scratch.get(key)
        if have is None:
            widths = [layer[0][0].shape[0 if layer[0][1] else -1] for layer in self.parts[:-1]]
            outs = [torch.ones(*stack, batch, n + 1, dtype=dtype) for n in widths]
            if not keep:
                self._scratch = {key: (outs,)}
                return (outs,)
            grads = [torch.empty(*stack, batch, n + 1, dtype=dtype) for n in widths]
            self._buffers[key] = have = (outs, grads)
        return have

    @torch.no_grad()
    def forward(
        self, x_ones: torch.Tensor, keep: bool = True, first: int | None = None
    ) -> torch.Tensor:
        """The network's output for inputs [x, 1] (:meth:`with_ones`).

        Args:
            x_ones: (B, in + 1) inputs with a column of ones.
            keep: Keep the layers' outputs for :meth:`backward` (a gradient step),
                until the next call; without, nothing is kept.
            first: Of stacked networks, run only the first ``first`` ones.

        Returns:
            (B, out), or (k, B, out) for k stacked networks.
        """
        weights = self._weight_blocks()
        if first is not None:
            weights = [w[:first] for w in weights]
        stack = tuple(weights[0].shape[:-2])
        bufs = self._layer_buffers(len(x_ones), x_ones.dtype, stack, keep)
        h = x_ones
        whole = self.act != "tanh"  # ReLU and ELU keep the ones: act(1) = 1
        for block, out in zip(weights[:-1], bufs[0], strict=True):
            z = _mm(h, block, out=out[..., :-1])
            _activation(out if whole else z, self.act)  # a whole buffer runs faster
            h = out
        if keep:
            self._last = (x_ones, bufs[0], bufs[1])
            self._last_weights, self._last_first = weights, first
        return _mm(h, weights[-1])

    @torch.no_grad()
    def backward(
        self,
        grad_out: torch.Tensor,
        rows: int | None = None,
        param_grads: bool = True,
        input_grad: slice | None = None,
    ) -> torch.Tensor | None:
        """Backpropagate dL/d(output) of the last :meth:`forward` with ``keep``.

        Args:
            grad_out: (B, out) dL/d(output), or (k, B, out) for k stacked networks.
            rows: Backpropagate only the first ``rows`` rows of the forward pass's batch
                (B of them); default all.
            param_grads: Write dL/dtheta into the parameters' ``.grad``, overwriting
                it; False where the network is held constant (a critic in the actor's
                loss), whose weight gradients are then never computed.
            input_grad: Also return dL/dx for these columns of x (summed over stacked
                networks), (B, columns).

        Returns:
            dL/dx, or None without ``input_grad``.
        """
        assert self._last is not None, "backward needs a forward pass first"
        if param_grads and self._last_first is not None:
            raise InvalidArgumentError(
                "ChainPasses.backward: a forward pass over the first stacked networks only "
                "has no parameter gradients; pass param_grads=False"
            )
        x_ones, outs, grads = self._last
        if rows is not None:
            x_ones = x_ones[:rows]
            outs, grads = [h[..., :rows, :] for h in outs], [g[..., :rows, :] for g in grads]
        weights = self._last_weights
        targets = self._grad_blocks() if param_grads else [None] * len(weights)
        inputs = [x_ones, *outs]
        g = grad_out
        for i in range(len(weights) - 1, -1, -1):
            if param_grads:
                target = targets[i]
                block = torch.empty_like(weights[i]) if target is None else target
                _mm(inputs[i].mT, g, out=block)  # [dW^T; db] = [h, 1]^T dz
                if target is None:  # not laid out as a block: computed here, then set
                    self._set_grads(i, block)
            if i > 0:  # dz [W; b]^T = [dh, dz b]: the last column is left unused, so that
                # act' runs over whole buffers (at the ones column it multiplies by 1 or 0)
                dh = _mm(g, weights[i].mT, out=grads[i - 1])
                g = activation_backward(dh, outs[i - 1], self.act, out=dh)[..., :-1]
        if input_grad is None:
            return None
        dx = _mm(g, weights[0][..., input_grad, :].mT)
        return dx.sum(0) if dx.dim() == 3 else dx


def _whole(tensors: Sequence[torch.Tensor]) -> torch.Tensor | None:
    """A 1-d tensor over the memory ``tensors`` share, where they tile it exactly, else None.

    Each tensor must be dense (its elements one stretch of memory, in any order of the
    axes) and the stretches must follow one another from the memory's start to its end.
    """
    first = tensors[0]
    storage, size = first.untyped_storage(), first.element_size()
    spans = []
    for t in tensors:
        if t.untyped_storage().data_ptr() != storage.data_ptr() or t.dtype != first.dtype:
            return None
        span = 1 + sum((n - 1) * s for n, s in zip(t.shape, t.stride(), strict=True) if n > 0)
        if span != t.numel():
            return None
        spans.append((t.storage_offset(), t.numel()))
    end = 0
    for start, n in sorted(spans):
        if start != end:
            return None
        end += n
    if end * size != storage.nbytes():
        return None
    whole: torch.Tensor = first.new_empty(0).set_(storage, 0, (end,))  # type: ignore[call-overload]
    return whole


@torch.no_grad()
def match_state_layout(optimizer: torch.optim.Optimizer) -> None:
    """Lay each per-parameter tensor of ``optimizer``'s state out in memory as its parameter.

    A fused Adam walks a parameter, its gradient and its moments as one stretch of
    memory each, so they must share one layout: a state loaded from a checkpoint written
    with a layer's own tensors (row-major moments) under a parameter that is a
    transposed view of a [W^T; b] block would be read in the wrong order. Where a
    group's parameters tile one tensor's memory (views of the blocks of one network),
    its moments are moved into one tensor each laid out alike, so that
    :func:`fused_adam_step` updates the group as one tensor. The values stay. Call it
    after ``optimizer.load_state_dict``.
    """
    for group in optimizer.param_groups:
        params = [p for p in group["params"] if p in optimizer.state]
        if not params:
            continue
        whole = _whole(params)
        first = optimizer.state[params[0]]
        for key in [k for k, v in first.items() if isinstance(v, torch.Tensor) and v.dim() > 0]:
            buffer = None if whole is None else torch.empty_like(whole)
            for p in params:
                st = optimizer.state[p]
                value = st[key]
                if buffer is not None:
                    view = buffer.as_strided(p.shape, p.stride(), p.storage_offset())
                    st[key] = view.copy_(value)
                elif value.stride() != p.stride():
                    st[key] = torch.empty_like(p).copy_(value)


def as_one_tensor(
    a: Sequence[torch.Tensor], b: Sequence[torch.Tensor]
) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """``a`` and ``b`` as one tensor each, where each tiles one tensor's memory alike.

    That is where a[i] lies at the same place of its memory as b[i] of its own (two
    networks of one shape laid out as blocks, such as a network and its target copy);
    else they are returned as they are. An elementwise update of the pairs (a Polyak
    average) then runs once, over whole tensors.
    """
    same = len(a) == len(b) and all(
        (x.shape, x.storage_offset(), x.stride()) == (y.shape, y.storage_offset(), y.stride())
        for x, y in zip(a, b, strict=True)
    )
    whole_a, whole_b = (_whole(a), _whole(b)) if same else (None, None)
    if whole_a is None or whole_b is None or len(whole_a) != len(whole_b):
        return list(a), list(b)
    return [whole_a], [whole_b]


def _flat_group(
    params: Sequence[torch.Tensor], states: Sequence[dict[str, Any]]
) -> tuple[torch.Tensor, ...] | None:
    """A group's parameters, gradients and moments as one tensor each, where they can be.

    That is where each of the four tiles one tensor's memory and every parameter, its
    gradient and its moments lie at the same place in theirs.
    """
    grads = [p.grad for p in params]
    lists = [params, grads, [s["exp_avg"] for s in states], [s["exp_avg_sq"] for s in states]]
    for i, p in enumerate(params):
        where = (p.storage_offset(), p.stride())
        if any((t[i].storage_offset(), t[i].stride()) != where for t in lists[1:]):
            return None
    wholes = [_whole(t) for t in lists]
    return None if any(w is None for w in wholes) else tuple(wholes)  # type: ignore[arg-type]


_FLAT_GROUPS: weakref.WeakKeyDictionary[torch.optim.Optimizer, dict[int, Any]] = (
    weakref.WeakKeyDictionary()
)


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

    A group whose parameters are views of one tensor's memory (the [W^T; b] blocks of a
    network), with gradients and moments laid out alike (:func:`match_state_layout`,
    which the first step runs), is updated as that one tensor: the same elementwise
    arithmetic, without the kernel's copies of strided views (the kernel's vectorised
    and scalar loops may round an element differently in the last place, so there the
    numbers agree with ``optimizer.step()`` to float rounding).

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
            match_state_layout(optimizer)
            return
        todo.append((g, params))
    cache = _FLAT_GROUPS.setdefault(optimizer, {})
    for i, (g, params) in enumerate(todo):
        if not params:
            continue
        st = [state[p] for p in params]
        steps = [s["step"] for s in st]
        for step in steps:  # one add_ each: _foreach_add_ costs more for a few tensors
            step.add_(1)
        tensors: list[list[torch.Tensor]] = [
            params, [p.grad for p in params], [s["exp_avg"] for s in st],
            [s["exp_avg_sq"] for s in st],
        ]  # fmt: skip
        if len(params) > 1:
            key = (tuple(p.data_ptr() for p in params), *(tuple(map(id, t)) for t in tensors[1:]))
            if key not in cache.get(i, {}):
                cache[i] = {key: _flat_group(params, st)}
            flat = cache[i][key]
            if flat is not None:  # every step tensor holds the same count
                tensors, steps = [[t] for t in flat], steps[:1]
        beta1, beta2 = g["betas"]
        torch._fused_adam_(
            tensors[0], tensors[1], tensors[2], tensors[3], [], steps,
            amsgrad=False, lr=g["lr"], beta1=beta1, beta2=beta2,
            weight_decay=g["weight_decay"], eps=g["eps"], maximize=False,
            grad_scale=None, found_inf=None,
        )  # fmt: skip
