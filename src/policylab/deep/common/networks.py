"""Neural networks of the deep agents: an MLP and the Nature DQN convolutional torso.

Every constructor takes a ``torch.Generator`` for its initial weights, so that a seed
fixes the network without touching torch's global random state.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from policylab.exceptions import InvalidArgumentError

__all__ = [
    "MLP",
    "ActorMLP",
    "NatureCNN",
    "TwinQNetwork",
    "build_torso",
    "clip_grad_norm",
    "init_layer",
    "is_image_space",
]

_ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU}


def init_layer(layer: nn.Module, gain: float, generator: torch.Generator | None) -> nn.Module:
    """Orthogonal weights scaled by ``gain`` and zero biases (the PPO/DQN custom)."""
    if isinstance(layer, nn.Linear | nn.Conv2d):
        nn.init.orthogonal_(layer.weight, gain=gain, generator=generator)
        if layer.bias is not None:
            nn.init.zeros_(layer.bias)
    return layer


def activation(name: str) -> type[nn.Module]:
    """The activation module class named ``name`` (tanh, relu, elu)."""
    try:
        return _ACTIVATIONS[name]
    except KeyError:
        raise InvalidArgumentError(
            f"activation must be one of {sorted(_ACTIVATIONS)}; got {name!r}"
        ) from None


class MLP(nn.Sequential):
    """A multilayer perceptron: Linear, activation, ..., Linear (no final activation).

    Args:
        in_dim: Input features.
        hidden: Sizes of the hidden layers (may be empty).
        out_dim: Output features; None ends with the last hidden layer's activation.
        act: Activation name (tanh, relu, elu).
        out_gain: Orthogonal gain of the output layer (0.01 for a policy head, 1 for a value).
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        in_dim: int,
        hidden: Sequence[int],
        out_dim: int | None,
        act: str = "tanh",
        out_gain: float = 1.0,
        generator: torch.Generator | None = None,
    ) -> None:
        layers: list[nn.Module] = []
        act_cls = activation(act)
        d = in_dim
        for h in hidden:
            layers += [init_layer(nn.Linear(d, h), math.sqrt(2), generator), act_cls()]
            d = h
        if out_dim is not None:
            layers.append(init_layer(nn.Linear(d, out_dim), out_gain, generator))
            d = out_dim
        super().__init__(*layers)
        self.out_dim = d

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """The layers in order, each called by its ``forward``.

        Skipping ``nn.Module.__call__`` (hooks on the inner layers do not run; hooks on
        the MLP itself do) saves about a tenth of a small PPO update's time.
        """
        for layer in self:
            x = layer.forward(x)
        return x


class NatureCNN(nn.Module):
    """The convolutional torso of Mnih et al. (2015): 3 conv layers and a 512-unit layer.

    Input: (B, C, 84, 84) uint8 frames (C stacked grey frames), scaled to [0, 1] here.

    Args:
        in_channels: Number of stacked frames C.
        image_size: Height and width of the frames (84 in the paper).
        features: Width of the last, fully connected layer.
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        in_channels: int,
        image_size: tuple[int, int] = (84, 84),
        features: int = 512,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        g = math.sqrt(2)
        self.conv = nn.Sequential(
            init_layer(nn.Conv2d(in_channels, 32, 8, stride=4), g, generator),
            nn.ReLU(),
            init_layer(nn.Conv2d(32, 64, 4, stride=2), g, generator),
            nn.ReLU(),
            init_layer(nn.Conv2d(64, 64, 3, stride=1), g, generator),
            nn.ReLU(),
            nn.Flatten(),
        )
        with torch.no_grad():
            n = self.conv(torch.zeros(1, in_channels, *image_size)).shape[1]
        self.fc = nn.Sequential(init_layer(nn.Linear(n, features), g, generator), nn.ReLU())
        self.out_dim = features

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Features of a batch of frame stacks."""
        out: torch.Tensor = self.fc(self.conv(x.float() / 255.0))
        return out


def is_image_space(space: gym.Space[object]) -> bool:
    """Whether observations are stacked images: a uint8 Box of shape (C, H, W)."""
    return isinstance(space, gym.spaces.Box) and space.dtype == np.uint8 and len(space.shape) == 3


def build_torso(
    space: gym.Space[object],
    hidden: Sequence[int],
    act: str,
    generator: torch.Generator | None,
) -> nn.Module:
    """The feature extractor for an observation space; ``.out_dim`` is its width.

    A (C, H, W) uint8 image gets a :class:`NatureCNN`; a flat Box gets an :class:`MLP`
    with the given hidden layers; a Discrete space is one-hot encoded first.
    """
    if is_image_space(space):
        assert isinstance(space, gym.spaces.Box)
        c, h, w = space.shape
        return NatureCNN(c, (h, w), generator=generator)
    if isinstance(space, gym.spaces.Discrete):
        return nn.Sequential(
            _OneHot(int(space.n)), MLP(int(space.n), hidden, None, act, generator=generator)
        )
    if isinstance(space, gym.spaces.Box):
        return nn.Sequential(
            nn.Flatten(), MLP(int(np.prod(space.shape)), hidden, None, act, generator=generator)
        )
    raise InvalidArgumentError(
        f"observation space must be a Box (vectors or uint8 images) or Discrete; got {space}"
    )


def torso_width(torso: nn.Module) -> int:
    """The number of features a :func:`build_torso` module outputs."""
    last = torso[-1] if isinstance(torso, nn.Sequential) else torso
    width = getattr(last, "out_dim", None)
    if not isinstance(width, int):
        raise InvalidArgumentError(f"{type(last).__name__} does not say its output width (out_dim)")
    return width


class _OneHot(nn.Module):
    def __init__(self, n: int) -> None:
        super().__init__()
        self.n = n

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return nn.functional.one_hot(x.long().reshape(-1), self.n).float()


def clip_grad_norm(params: Sequence[torch.Tensor], max_norm: float) -> float:
    """Scale the gradients of ``params`` so that their global L2 norm is at most ``max_norm``.

    g <- g * min(1, max_norm / (||g||_2 + 1e-6)), with ||g||_2 over all gradients
    together (what ``torch.nn.utils.clip_grad_norm_`` does, with less per-call
    overhead for the small networks of classic control). Returns the norm before clipping.
    """
    grads = [p.grad for p in params if p.grad is not None]
    if not grads:
        return 0.0
    norm = torch.linalg.vector_norm(torch.stack(torch._foreach_norm(grads)))
    coef = torch.clamp(max_norm / (norm + 1e-6), max=1.0)
    torch._foreach_mul_(grads, coef)
    return float(norm)


class TwinQNetwork(nn.Module):
    """Two critics Q_1(s, a), Q_2(s, a) evaluated together (SAC, TD3).

    Each layer of the two MLPs is one (2, in, out) weight tensor, so both critics run as
    one batched matrix product per layer (``torch.bmm``/``torch.baddbmm``): half the
    kernel launches of two separate networks, with the same arithmetic. The first layer
    W_s s + W_a a + b (the same layer as W [s; a] + b) is stored as W_s, W_a and b and
    computed as one product [s, a, 1] [W_s; W_a; b], which copies no bias into its
    output; the one-output last layer is an element-wise product and a sum, which a CPU
    runs about ten times faster than a matrix product with one output column. Weights
    are orthogonal (gain sqrt(2) in hidden layers, 1 at the output), biases zero.

    Each layer's parameters are views of one block [W; b] of both critics (see
    :meth:`lay_out_blocks`), on which the hand-written passes of
    :class:`~policylab.deep.common.mlp_grad.ChainPasses` run one batched product per
    layer and pass.

    Args:
        obs_dim: Observation features.
        action_dim: Action dimensions.
        hidden: Hidden layer sizes of each critic (at least one layer).
        act: Activation name (tanh, relu, elu).
        generator: Generator of the initial weights.
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        hidden: Sequence[int],
        act: str = "relu",
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        if not hidden:
            raise InvalidArgumentError("the twin critics need at least one hidden layer")
        dims = [obs_dim + action_dim, *hidden, 1]
        self.obs_dim = obs_dim
        self.weights = nn.ParameterList()
        self.biases = nn.ParameterList()
        for i, (d_in, d_out) in enumerate(itertools.pairwise(dims)):
            w = torch.empty(2, d_in, d_out)
            gain = 1.0 if i == len(dims) - 2 else math.sqrt(2)
            for k in range(2):  # orthogonal init acts on (out, in) matrices
                w[k] = nn.init.orthogonal_(torch.empty(d_out, d_in), gain, generator).T
            if i == 0:
                self.weights.append(nn.Parameter(w[:, :obs_dim].contiguous()))
                self.weights.append(nn.Parameter(w[:, obs_dim:].contiguous()))
            else:
                self.weights.append(nn.Parameter(w))
            self.biases.append(nn.Parameter(torch.zeros(2, 1, d_out)))
        act_cls = activation(act)
        # in place where the activation allows it (its input is no saved tensor)
        self.act = act_cls(inplace=True) if act_cls in (nn.ReLU, nn.ELU) else act_cls()
        self.lay_out_blocks()

    def block_parts(self) -> list[list[tuple[torch.Tensor, bool]]]:
        """Each layer's parameters in the order of its block [W; b], (2, in + 1, out).

        The first layer's block is [W_s; W_a; b]; every part is held as it is (not
        transposed), the form :class:`~policylab.deep.common.mlp_grad.ChainPasses`
        takes.
        """
        ws, bs = list(self.weights), list(self.biases)
        first = [(ws[0], False), (ws[1], False), (bs[0], False)]
        return [first, *([(ws[i + 1], False), (bs[i], False)] for i in range(1, len(bs)))]

    @torch.no_grad()
    def lay_out_blocks(self, grads: bool = False) -> None:
        """Move each layer's parameters into one block [W; b] of both critics (same values).

        The block (2, in + 1, out) lies in memory as (in + 1, 2, out), so that each
        parameter is one stretch of memory (which a fused optimizer needs) while both
        critics' blocks are strided views for one batched product. A copy of the
        network (``copy.deepcopy``) holds its own tensors until this is called on it.

        Args:
            grads: Also give the parameters gradients (zero) laid out alike in one
                tensor, so that an optimizer step can update all of them as one tensor
                (without, they lose any gradient they have).
        """
        layers = self.block_parts()
        first = layers[0][0][0]
        flat = first.new_empty(sum(p.numel() for layer in layers for p, _ in layer))
        grad_flat = torch.zeros_like(flat) if grads else None
        offset = 0
        for layer in layers:
            k, n_out = first.shape[0], layer[0][0].shape[-1]
            n = sum(p.shape[-2] for p, _ in layer)
            block = flat[offset : offset + n * k * n_out].view(n, k, n_out).permute(1, 0, 2)
            row = 0
            for p, _ in layer:
                view = block[:, row : row + p.shape[-2]]
                view.copy_(p)
                p.data = view
                p.grad = (
                    None
                    if grad_flat is None
                    else grad_flat.as_strided(view.shape, view.stride(), view.storage_offset())
                )
                row += p.shape[-2]
            offset += n * k * n_out

    def forward(
        self,
        obs: torch.Tensor,
        actions: torch.Tensor,
        params: Sequence[torch.Tensor] | None = None,
    ) -> torch.Tensor:
        """(2, B) Q_1(s, a) and Q_2(s, a) for a batch of (B, obs_dim) and (B, action_dim).

        ``params`` (weights then biases, as :meth:`parameters` orders them) evaluates the
        critics with other tensors, e.g. detached ones, so that an actor's loss gets no
        critic weight gradients; their first-axis slices ``[:1]`` evaluate Q_1 alone
        (shape (1, B)).
        """
        ps = list(self.parameters()) if params is None else list(params)
        n = len(ps) // 2  # n + 1 weights (the first layer's two) and n biases
        ws, bs = ps[: n + 1], ps[n + 1 :]
        k = len(ws[0])  # 2, or 1 with the first critic's tensors alone
        # the first layer as one product [s, a, 1] [W_s; W_a; b]: no bias copied into the
        # output and one matrix product instead of two
        x = torch.cat([obs.reshape(len(obs), -1), actions, obs.new_ones((len(obs), 1))], 1)
        h = torch.bmm(x.unsqueeze(0).expand(k, -1, -1), torch.cat([ws[0], ws[1], bs[0]], 1))
        for i in range(1, n - 1):
            h = torch.baddbmm(bs[i], self.act(h), ws[i + 1])
        # the one-output layer as a product and a sum: a matrix product with one output
        # column (and its backward, an outer product) runs about 10x slower on a CPU
        w_out = ws[n].reshape(k, 1, -1)
        q: torch.Tensor = (self.act(h) * w_out).sum(-1) + bs[n - 1].reshape(k, 1)
        return q


class ActorMLP(nn.Module):
    """The MLP of a continuous-action actor: ``heads`` outputs per action dimension.

    The output layer starts small (orthogonal gain 0.01), so the first actions sit near
    the middle of the action space.

    Args:
        obs_dim: Observation features.
        action_dim: m, the action dimensions.
        hidden: Hidden layer sizes.
        act: Activation name (tanh, relu, elu).
        generator: Generator of the initial weights.
        heads: Outputs per action dimension (1: an action; 2: a mean and a log std).
    """

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        hidden: Sequence[int],
        act: str = "relu",
        generator: torch.Generator | None = None,
        heads: int = 1,
    ) -> None:
        super().__init__()
        self.action_dim = action_dim
        self.net = MLP(obs_dim, hidden, heads * action_dim, act, out_gain=0.01, generator=generator)

    def features(self, obs: torch.Tensor) -> torch.Tensor:
        """The MLP's (B, heads * m) outputs for a batch of observations."""
        out: torch.Tensor = self.net(obs.reshape(len(obs), -1))
        return out
