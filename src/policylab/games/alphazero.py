"""AlphaZero (Silver et al., 2017/2018): self-play with PUCT search guided by a policy-value net.

One iteration:

1. **Self-play.** Games of the current best network against itself, in parallel
   worker processes or Ray tasks (the same games either way). Each move runs PUCT
   search from the position: a simulation descends by

       a = argmax_a  Q(s, a) + c_puct * P(s, a) * sqrt(N(s)) / (1 + N(s, a)),

   expands the leaf with the network's priors P and scores it with the network's
   value v (a finished game scores its outcome) and backs v up the path, negated
   at each level. Dirichlet noise mixes into the root priors,
   P = (1 - eps) p + eps * Dir(alpha), and the move is sampled from the visit counts
   with temperature 1 for the first moves, then taken greedily. Each position is
   stored with the search policy pi(a) = N(s0, a) / sum_b N(s0, b) and the final
   outcome z for the player to move there.
2. **Training** on minibatches from the replay of recent games (each sample in a
   random one of the board's symmetries: the eight of the square for tic-tac-toe,
   the mirror image for Connect Four) with the loss  (z - v)^2 - pi . log p  (plus
   weight decay).
3. **Evaluation**: the trained network plays the best one; it replaces the best if
   it scores at least ``accept_score`` (wins + draws / 2 over games).

The run folder keeps an atomic checkpoint after every iteration (networks,
optimizer, replay, counters) and resumes from it. Ctrl-C or SIGTERM stops at once,
keeping the checkpoint of the last whole iteration, and ends the self-play workers
(which also end by themselves if the training process dies).

With ``backend="ray"`` the workers are Ray tasks running the same function as the
processes: on a local Ray started for the run with ``workers`` CPUs (and shut down at
its end), or on the running cluster at ``ray_address``, whose nodes need policylab
installed.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing import active_children, get_context
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from policylab.exceptions import CheckpointError, InvalidArgumentError, TrainingInterrupted
from policylab.games.base import Game, GameState
from policylab.games.registry import get_game

if TYPE_CHECKING:
    import torch
    from rich.console import Console

    from policylab.runs import RunFolder

__all__ = [
    "PUCT",
    "AlphaZeroConfig",
    "AlphaZeroPlayer",
    "default_config",
    "train_alphazero",
]

RESUME_SETTINGS = ("iterations", "workers", "backend", "ray_address")
"""The settings a resumed run may change: how long it runs and where its self-play runs."""

BACKENDS = ("processes", "ray")
"""Where AlphaZero's self-play workers can run (:attr:`AlphaZeroConfig.backend`)."""

SYMMETRIES: dict[str, tuple[tuple[int, bool], ...]] = {
    "tic-tac-toe": tuple((k, f) for f in (False, True) for k in range(4)),
    "connect-four": ((0, False), (0, True)),
}
"""The symmetries of each game's board: (quarter turns, mirrored first), the identity first.

Tic-tac-toe has the eight of the square; Connect Four (gravity) only the mirror image.
"""


def transform_board(x: NDArray[Any], turns: int, mirrored: bool) -> NDArray[Any]:
    """Boards ``x`` (..., rows, cols) mirrored left to right if asked, then turned by quarters."""
    if mirrored:
        x = x[..., ::-1]
    return np.rot90(x, turns, axes=(-2, -1))


def symmetries(game: Game) -> list[tuple[int, bool, NDArray[np.int64]]]:
    """Each board symmetry of ``game`` with its action permutation.

    A triple (turns, mirrored, perm): the board ``transform_board(x, turns, mirrored)``
    has the search policy ``pi[perm]`` (action j of the new board is action perm[j] of
    the old one).
    """
    if game.n_actions == game.rows * game.cols:  # one action per cell
        grid = np.arange(game.n_actions).reshape(game.rows, game.cols)
    else:  # one action per column
        grid = np.tile(np.arange(game.cols), (game.rows, 1))
    out = []
    for turns, mirrored in SYMMETRIES[game.name]:
        t = transform_board(grid, turns, mirrored)
        perm = t.ravel() if game.n_actions == game.rows * game.cols else t[0]
        out.append((turns, mirrored, np.ascontiguousarray(perm, dtype=np.int64)))
    return out


@dataclass(frozen=True)
class AlphaZeroConfig:
    """Settings of an AlphaZero run (see :func:`default_config` for each game's defaults).

    Attributes:
        iterations: Self-play / train / evaluate iterations in all.
        games_per_iteration: Self-play games per iteration.
        simulations: PUCT simulations per move in self-play.
        eval_simulations: PUCT simulations per move in evaluation and play.
        c_puct: Exploration constant of PUCT.
        dirichlet_alpha: Concentration of the root noise.
        noise_fraction: Share eps of noise in the root priors.
        temperature_moves: Moves of each self-play game sampled at temperature 1.
        random_openings: Share of self-play games that open with one uniformly random
            move per player (the lines a strong player rarely picks get visited too).
        replay_games: Recent games kept for training.
        train_steps: Minibatch updates per iteration.
        batch_size: Positions per minibatch.
        lr: Adam step size.
        weight_decay: L2 penalty.
        channels: Width of the residual network.
        blocks: Residual blocks.
        eval_games: Games of the new network against the best per iteration (0: always accept).
        accept_score: Score (wins + draws / 2 per game) the new network needs to become best.
        workers: Self-play workers: processes, or Ray tasks with ``backend="ray"``
            (0: in this process).
        parallel_games: Self-play games each worker plays side by side, their search
            leaves evaluated by the network in one batch (the same games whatever
            ``workers`` and ``backend`` are).
        backend: Where the self-play workers run: ``"processes"`` (worker processes on
            this machine) or ``"ray"`` (Ray tasks: a local Ray with ``workers`` CPUs, or
            the cluster at ``ray_address``; needs the ``sweep`` extra).
        ray_address: A running Ray cluster's address (``HOST:PORT``, ``ray://HOST:PORT``
            or ``auto``) for ``backend="ray"``; None starts a local Ray for the run.
        seed: Seed of the whole run.
    """

    iterations: int = 40
    games_per_iteration: int = 100
    simulations: int = 100
    eval_simulations: int = 100
    c_puct: float = 1.5
    dirichlet_alpha: float = 1.0
    noise_fraction: float = 0.25
    temperature_moves: int = 10
    random_openings: float = 0.0
    replay_games: int = 2000
    train_steps: int = 300
    batch_size: int = 256
    lr: float = 1e-3
    weight_decay: float = 1e-4
    channels: int = 64
    blocks: int = 4
    eval_games: int = 20
    accept_score: float = 0.55
    workers: int = 2
    parallel_games: int = 32
    backend: str = "processes"
    ray_address: str | None = None
    seed: int = 0

    def validate(self) -> None:
        """Raise InvalidArgumentError on a setting outside its range."""
        positive = [
            "iterations",
            "games_per_iteration",
            "simulations",
            "eval_simulations",
            "replay_games",
            "train_steps",
            "batch_size",
            "channels",
            "parallel_games",
        ]
        for name in positive:
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise InvalidArgumentError(
                    f"alphazero: {name} must be a positive integer; got {v!r}"
                )
        for name in ("blocks", "eval_games", "workers", "temperature_moves"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 0:
                raise InvalidArgumentError(f"alphazero: {name} must be an integer >= 0; got {v!r}")
        for name, lo, hi in (
            ("noise_fraction", 0, 1),
            ("accept_score", 0, 1),
            ("random_openings", 0, 1),
        ):
            v = getattr(self, name)
            if not lo <= v <= hi:
                raise InvalidArgumentError(f"alphazero: {name} must be in [{lo}, {hi}]; got {v!r}")
        for name in ("c_puct", "dirichlet_alpha", "lr"):
            if not getattr(self, name) > 0:
                raise InvalidArgumentError(
                    f"alphazero: {name} must be > 0; got {getattr(self, name)!r}"
                )
        if self.weight_decay < 0:
            raise InvalidArgumentError(
                f"alphazero: weight_decay must be >= 0; got {self.weight_decay!r}"
            )
        if self.backend not in BACKENDS:
            raise InvalidArgumentError(
                f"alphazero: backend must be one of {', '.join(BACKENDS)}; got {self.backend!r}"
            )
        if self.backend == "ray" and self.workers < 1:
            raise InvalidArgumentError(
                "alphazero: backend=ray runs the self-play workers as Ray tasks; workers must "
                f"be >= 1; got {self.workers}"
            )
        if self.ray_address is not None:
            if self.backend != "ray":
                raise InvalidArgumentError(
                    f"alphazero: ray_address={self.ray_address!r} needs backend=ray; "
                    f"got backend={self.backend!r}"
                )
            if not isinstance(self.ray_address, str):
                raise InvalidArgumentError(
                    f"alphazero: ray_address must be HOST:PORT; got {self.ray_address!r}"
                )
            from policylab.cluster import parse_address

            parse_address(self.ray_address, "alphazero: ray_address")


def default_config(game: str | Game, **overrides: Any) -> AlphaZeroConfig:
    """The default settings for a game, with ``overrides`` (unknown names are refused)."""
    g = get_game(game)
    base: dict[str, Any] = {}
    if g.name == "tic-tac-toe":
        base = dict(
            iterations=15,
            games_per_iteration=60,
            simulations=50,
            eval_simulations=50,
            dirichlet_alpha=1.0,
            # every move sampled: greedy late moves never show the network a fork it
            # walked into, and it rated such lost positions as won
            temperature_moves=9,
            replay_games=600,
            train_steps=200,
            batch_size=128,
            channels=32,
            blocks=2,
            eval_games=10,
            accept_score=0.5,  # good players draw every game: a draw-level score is enough
            random_openings=0.5,
        )
    elif g.name == "connect-four":
        # about 95 minutes on one core (about 45 s an iteration measured here): a small
        # residual network (48 channels, 3 blocks) whose leaves are evaluated 48 games at
        # a time; after 125 iterations it beat UCT with 1000 simulations in 89 of 100 games
        base = dict(
            iterations=125,
            games_per_iteration=96,
            simulations=100,
            eval_simulations=200,
            dirichlet_alpha=1.0,
            temperature_moves=12,
            replay_games=1000,
            train_steps=100,
            batch_size=256,
            channels=48,
            blocks=3,
            eval_games=0,  # a short run gains more from games than from gating them
            workers=1,
            parallel_games=48,
        )
    known = {f.name for f in dataclasses.fields(AlphaZeroConfig)}
    bad = set(overrides) - known
    if bad:
        raise InvalidArgumentError(
            f"unknown alphazero setting(s) {', '.join(sorted(bad))}; "
            f"known: {', '.join(sorted(known))}"
        )
    cfg = AlphaZeroConfig(**{**base, **overrides})
    cfg.validate()
    return cfg


# ---------------------------------------------------------------- the network


def make_network(game: Game, channels: int, blocks: int) -> torch.nn.Module:
    """A residual policy-value network: planes (2, rows, cols) -> (logits over actions, value)."""
    import torch
    from torch import nn

    class Block(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.c1 = nn.Conv2d(channels, channels, 3, padding=1, bias=False)
            self.b1 = nn.BatchNorm2d(channels)
            self.c2 = nn.Conv2d(channels, channels, 3, padding=1, bias=False)
            self.b2 = nn.BatchNorm2d(channels)

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            y = torch.relu(self.b1(self.c1(x)))
            return torch.relu(x + self.b2(self.c2(y)))

    class Net(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            cells = game.rows * game.cols
            self.stem = nn.Sequential(
                nn.Conv2d(2, channels, 3, padding=1, bias=False),
                nn.BatchNorm2d(channels),
                nn.ReLU(),
            )
            self.tower = nn.Sequential(*[Block() for _ in range(blocks)])
            self.policy = nn.Sequential(
                nn.Conv2d(channels, 2, 1),
                nn.ReLU(),
                nn.Flatten(),
                nn.Linear(2 * cells, game.n_actions),
            )
            self.value = nn.Sequential(
                nn.Conv2d(channels, 1, 1),
                nn.ReLU(),
                nn.Flatten(),
                nn.Linear(cells, 64),
                nn.ReLU(),
                nn.Linear(64, 1),
                nn.Tanh(),
            )

        def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            h = self.tower(self.stem(x))
            return self.policy(h), self.value(h).squeeze(-1)

    return Net()


Evaluator = Callable[[Sequence[GameState]], tuple[NDArray[np.float64], NDArray[np.float64]]]
"""A batch of positions -> (priors (B, actions), zero on illegal moves; values (B,)).

Values are for the player to move in each position.
"""


def net_evaluator(net: torch.nn.Module) -> Evaluator:
    """The network's priors over legal moves and values, in one forward pass per batch."""
    import torch

    net.eval()

    def evaluate(states: Sequence[GameState]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        x = np.stack([s.encode() for s in states])
        with torch.inference_mode():
            logits, v = net(torch.from_numpy(x))
        lg = logits.double().numpy()
        mask = np.stack([s.action_mask() for s in states]).astype(bool)
        lg = np.where(mask, lg, -np.inf)
        p = np.exp(lg - lg.max(axis=1, keepdims=True))
        return p / p.sum(axis=1, keepdims=True), v.double().numpy()

    return evaluate


# ---------------------------------------------------------------- PUCT search


class _Node:
    """A position in the search tree; the edge statistics are per legal move, in order."""

    __slots__ = ("children", "legal", "n", "p", "state", "terminal", "total", "value", "w")

    def __init__(self, state: GameState) -> None:
        self.state = state
        self.terminal = state.is_terminal()
        self.value = state.outcome(state.player) if self.terminal else 0.0
        self.legal = state.legal_actions()
        k = len(self.legal)
        self.p: list[float] = []  # filled when the network expands the node
        self.n = [0] * k
        self.w = [0.0] * k
        self.total = 0
        self.children: list[_Node | None] = [None] * k

    def select(self, c_puct: float) -> int:
        """The index (into ``legal``) of the move with the largest Q + U (the first among ties)."""
        sq = c_puct * math.sqrt(max(self.total, 1))
        best, best_i = -math.inf, 0
        for i, (n, w, p) in enumerate(zip(self.n, self.w, self.p, strict=True)):
            score = (w / n if n else 0.0) + sq * p / (1 + n)
            if score > best:
                best, best_i = score, i
        return best_i


def _backup(path: list[tuple[_Node, int]], value: float) -> None:
    """Back ``value`` (for the player to move at the leaf) up ``path``, negated at each level."""
    for node, i in reversed(path):
        value = -value
        node.n[i] += 1
        node.w[i] += value
        node.total += 1


class PUCT:
    """AlphaZero's tree search: PUCT selection, network priors and values at the leaves.

    :meth:`visit_counts_many` searches several positions at once (the self-play games
    of one process) and evaluates their leaves in one batch: one forward pass of the
    network per simulation for all of them, instead of one per position.
    """

    def __init__(self, evaluate: Evaluator, simulations: int, c_puct: float = 1.5) -> None:
        if simulations < 1:
            raise InvalidArgumentError(f"PUCT needs at least one simulation; got {simulations}")
        self.evaluate = evaluate
        self.simulations = simulations
        self.c_puct = c_puct

    def visit_counts(
        self,
        state: GameState,
        noise: tuple[float, float] | None = None,
        rng: np.random.Generator | None = None,
    ) -> NDArray[np.float64]:
        """N(s0, a) after the search; ``noise`` = (alpha, eps) mixes Dirichlet noise into P(s0)."""
        counts: NDArray[np.float64] = self.visit_counts_many(
            [state], noise, None if rng is None else [rng]
        )[0]
        return counts

    def visit_counts_many(
        self,
        states: Sequence[GameState],
        noise: tuple[float, float] | None = None,
        rngs: Sequence[np.random.Generator] | None = None,
    ) -> NDArray[np.float64]:
        """N(s0, a) for each position (rows), searched side by side with batched leaves.

        Args:
            states: Non-terminal positions, each searched in its own tree.
            noise: (alpha, eps): root priors P = (1 - eps) p + eps Dir(alpha), with
                ``rngs[i]`` drawing the noise of ``states[i]``.
            rngs: One generator per position (needed with ``noise``).

        Raises:
            InvalidArgumentError: If a position is over, or noise comes without generators.
        """
        for s in states:
            if s.is_terminal():
                raise InvalidArgumentError(
                    f"{s.game.name}: cannot search from a finished game ({s.position_string()!r})"
                )
        if noise is not None and (rngs is None or len(rngs) != len(states)):
            raise InvalidArgumentError("PUCT: root noise needs one generator per position")
        roots = [_Node(s) for s in states]
        p, _ = self.evaluate(states)
        for k, root in enumerate(roots):
            pr = p[k, list(root.legal)]
            if noise is not None and rngs is not None:
                alpha, eps = noise
                pr = (1 - eps) * pr + eps * rngs[k].dirichlet([alpha] * len(root.legal))
            root.p = pr.tolist()
        c = self.c_puct
        for _ in range(self.simulations):
            leaves: list[tuple[_Node, list[tuple[_Node, int]]]] = []
            for root in roots:
                node, path = root, []
                while True:
                    i = node.select(c)
                    path.append((node, i))
                    child = node.children[i]
                    if child is None:
                        child = node.children[i] = _Node(node.state._apply(node.legal[i]))
                        node = child
                        break
                    node = child
                    if node.terminal:
                        break
                if node.terminal:  # a finished game scores its outcome
                    _backup(path, node.value)
                else:
                    leaves.append((node, path))
            if leaves:
                p, v = self.evaluate([leaf.state for leaf, _ in leaves])
                for k, (leaf, path) in enumerate(leaves):
                    leaf.p = p[k, list(leaf.legal)].tolist()
                    _backup(path, float(v[k]))
        counts = np.zeros((len(states), states[0].game.n_actions) if states else (0, 0))
        for k, root in enumerate(roots):
            counts[k, list(root.legal)] = root.n
        return counts


class AlphaZeroPlayer:
    """Plays the most visited move of a PUCT search with a trained network (no noise)."""

    def __init__(
        self,
        net: torch.nn.Module,
        game: Game,
        simulations: int,
        c_puct: float,
        name: str = "alphazero",
    ) -> None:
        self.net = net
        self.game = game
        self.search = PUCT(net_evaluator(net), simulations, c_puct)
        self.name = name

    def choose(self, state: GameState) -> int:
        """The most visited move (the first among ties); torch on one thread (small nets)."""
        return self.choose_many([state])[0]

    def choose_many(self, states: Sequence[GameState]) -> list[int]:
        """:meth:`choose` in each position, searched side by side (leaves in one batch)."""
        from policylab.deep.common.agent import _TorchThreads

        with _TorchThreads(1):
            counts = self.search.visit_counts_many(states)
        return [int(np.argmax(row)) for row in counts]

    @classmethod
    def from_checkpoint(
        cls,
        meta: dict[str, Any],
        tensors: dict[str, Any],
        game: Game,
        name: str = "alphazero",
        seed: int | np.random.Generator | None = None,
    ) -> AlphaZeroPlayer:
        """The best network of a checkpoint as a player."""
        cfg = AlphaZeroConfig(**meta["config"])
        net = make_network(game, cfg.channels, cfg.blocks)
        try:
            net.load_state_dict(tensors["best"])
        except (KeyError, RuntimeError) as e:
            raise CheckpointError(
                f"the checkpoint's network does not fit its config: {e}"
            ) from None
        return cls(net, game, cfg.eval_simulations, cfg.c_puct, name=name)


# ---------------------------------------------------------------- self-play


SelfPlayGame = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]
"""One self-play game: (planes, search policies, outcomes for the player to move)."""


def play_selfplay_games(
    game: Game, evaluate: Evaluator, cfg: AlphaZeroConfig, seeds: Sequence[int]
) -> list[SelfPlayGame]:
    """Self-play games, one per seed, played side by side (their leaves evaluated in batches).

    Each game draws its opening, root noise and sampled moves from its own generator
    (seeded by its seed), so a game does not depend on the others it is played with
    beyond the rounding of the batched network evaluation.
    """
    rngs = [np.random.default_rng(s) for s in seeds]
    search = PUCT(evaluate, cfg.simulations, cfg.c_puct)
    states: list[GameState] = []
    for rng in rngs:
        s = game.initial()
        if rng.random() < cfg.random_openings:
            for _ in range(2):
                s = s.play(int(rng.choice(s.legal_actions())))
        states.append(s)
    planes: list[list[NDArray[np.float32]]] = [[] for _ in seeds]
    pis: list[list[NDArray[np.float32]]] = [[] for _ in seeds]
    players: list[list[int]] = [[] for _ in seeds]
    live = [i for i, s in enumerate(states) if not s.is_terminal()]
    while live:
        counts = search.visit_counts_many(
            [states[i] for i in live],
            (cfg.dirichlet_alpha, cfg.noise_fraction),
            [rngs[i] for i in live],
        )
        for row, i in zip(counts, live, strict=True):
            s, rng = states[i], rngs[i]
            pi = row / row.sum()
            planes[i].append(s.encode())
            pis[i].append(pi.astype(np.float32))
            players[i].append(s.player)
            if len(s.moves) < cfg.temperature_moves:
                a = int(rng.choice(len(pi), p=pi))
            else:
                best = np.flatnonzero(row == row.max())
                a = int(best[rng.integers(len(best))])
            states[i] = s.play(a)
        live = [i for i in live if not states[i].is_terminal()]
    out = []
    for i, s in enumerate(states):
        z = np.array([s.outcome(p) for p in players[i]], dtype=np.float32)
        if not players[i]:  # a game the random opening ended (not on these boards)
            out.append(
                (
                    np.zeros((0, 2, game.rows, game.cols), np.float32),
                    np.zeros((0, game.n_actions), np.float32),
                    z,
                )
            )
        else:
            out.append((np.stack(planes[i]), np.stack(pis[i]), z))
    return out


def _worker_init(parent: int) -> None:
    """Start of a self-play worker: die with the training process, leave Ctrl-C to it.

    On Linux the kernel sends the worker SIGTERM when its parent ends, however it ends
    (``prctl(PR_SET_PDEATHSIG)``); a parent already gone by then ends the worker at once.
    SIGINT is ignored: a Ctrl-C in the terminal reaches the whole process group, and the
    training process decides what to stop.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes

        pr_set_pdeathsig = 1
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(pr_set_pdeathsig, signal.SIGTERM, 0, 0, 0)
    if os.getppid() != parent:
        os._exit(1)


def _worker_games(
    game_name: str,
    cfg_dict: dict[str, Any],
    weights: dict[str, NDArray[Any]],
    batches: list[list[int]],
) -> list[SelfPlayGame]:
    """A self-play worker's share: batches of seeds, each batch played side by side."""
    import torch

    torch.set_num_threads(1)
    game = get_game(game_name)
    cfg = AlphaZeroConfig(**cfg_dict)
    net = make_network(game, cfg.channels, cfg.blocks)
    net.load_state_dict({k: torch.from_numpy(v) for k, v in weights.items()})
    ev = net_evaluator(net)
    return [g for seeds in batches for g in play_selfplay_games(game, ev, cfg, seeds)]


WorkerArgs = tuple[str, dict[str, Any], dict[str, NDArray[Any]]]
"""What every self-play worker of an iteration gets: (game name, config, best weights)."""


class _ProcessWorkers:
    """Self-play workers as processes on this machine (a spawn pool)."""

    def __init__(self, workers: int) -> None:
        self.pool = get_context("spawn").Pool(workers, _worker_init, (os.getpid(),))
        self.pids = {p.pid for p in active_children()}

    def play(
        self, args: WorkerArgs, chunks: list[list[list[int]]], poll: Callable[[], None]
    ) -> list[list[SelfPlayGame]]:
        """:func:`_worker_games` on each chunk of seed batches; ``poll`` is called while waiting."""
        pending = [self.pool.apply_async(_worker_games, (*args, c)) for c in chunks]
        for r in pending:
            while not r.ready():  # a signal is seen within a tenth of a second
                poll()
                if not self.pids <= {p.pid for p in active_children()}:
                    raise RuntimeError(  # the pool would wait for it forever
                        "a self-play worker process died (killed, or out of memory); the last "
                        "checkpoint is kept: continue with --resume"
                    )
                r.wait(0.1)
        return [r.get() for r in pending]

    def close(self, finished: bool) -> None:
        """End the workers: after their work if ``finished``, else at once."""
        if finished:
            self.pool.close()
        else:
            self.pool.terminate()
        self.pool.join()


class _RayWorkers:
    """Self-play workers as Ray tasks running :func:`_worker_games`.

    Without an address a local Ray with ``workers`` CPUs starts for the run and is shut
    down at its end; with one, the run joins that cluster (an unreachable address is
    refused within seconds) and leaves it running. A process already connected to Ray
    keeps its connection.
    """

    def __init__(self, workers: int, address: str | None) -> None:
        from policylab.cluster import connect, import_ray

        what = "alphazero's backend=ray"
        self.ray = import_ray(what)
        main = threading.current_thread() is threading.main_thread()
        self.sigterm = signal.getsignal(signal.SIGTERM) if main else None  # ray.init sets one
        try:
            self.started = connect(address, workers, option="alphazero: ray_address", what=what)
        except BaseException:
            self._restore_sigterm()
            raise
        self.task = self.ray.remote(num_cpus=1)(_worker_games)
        self.pending: list[Any] = []

    def play(
        self, args: WorkerArgs, chunks: list[list[list[int]]], poll: Callable[[], None]
    ) -> list[list[SelfPlayGame]]:
        """:func:`_worker_games` on each chunk of seed batches; ``poll`` is called while waiting."""
        ray = self.ray
        name, cfg, weights = args
        shared = ray.put(weights)  # sent to the cluster once, read by every task
        self.pending = [self.task.remote(name, cfg, shared, c) for c in chunks]
        waiting = list(self.pending)
        try:
            while waiting:  # a signal is seen within a tenth of a second
                poll()
                _, waiting = ray.wait(waiting, num_returns=len(waiting), timeout=0.1)
            results: list[list[SelfPlayGame]] = ray.get(self.pending)
        except ray.exceptions.RayError as e:
            raise RuntimeError(
                f"a self-play task failed on Ray ({type(e).__name__}: "
                f"{str(e).strip().splitlines()[-1] if str(e).strip() else 'no message'}); "
                "the last checkpoint is kept: continue with --resume"
            ) from None
        self.pending = []
        return results

    def close(self, finished: bool) -> None:
        """Cancel unfinished tasks; shut down the local Ray if this run started it."""
        ray = self.ray
        for ref in self.pending:
            with contextlib.suppress(Exception):
                ray.cancel(ref, force=True)
        self.pending = []
        if self.started:
            ray.shutdown()
        self._restore_sigterm()

    def _restore_sigterm(self) -> None:
        if self.sigterm is not None:
            signal.signal(signal.SIGTERM, self.sigterm)


def check_ray_backend(cfg: AlphaZeroConfig) -> None:
    """With ``backend="ray"``: refuse, within seconds, a missing Ray or an unreachable address.

    Raises:
        InvalidArgumentError: Ray is not installed, or nothing answers at ``ray_address``.
    """
    if cfg.backend != "ray":
        return
    from policylab.cluster import import_ray, probe_address

    import_ray("alphazero's backend=ray")
    if cfg.ray_address is not None:
        probe_address(cfg.ray_address, option="alphazero: ray_address")


def _ray_settings(address: Any) -> AlphaZeroConfig:
    """Settings with ``backend="ray"`` and ``address`` (checked), to check a resume's change."""
    cfg = AlphaZeroConfig(backend="ray", ray_address=address)
    cfg.validate()
    return cfg


def _start_workers(cfg: AlphaZeroConfig) -> _ProcessWorkers | _RayWorkers | None:
    """The self-play workers of ``cfg`` (None: self-play in this process)."""
    if cfg.workers == 0:
        return None
    if cfg.backend == "ray":
        return _RayWorkers(cfg.workers, cfg.ray_address)
    return _ProcessWorkers(cfg.workers)


def _match(game: Game, a: AlphaZeroPlayer, b: AlphaZeroPlayer, games: int, seed: int) -> float:
    """A's score (wins + draws / 2 per game); the first two moves of each game are random.

    A moves first in the even games (before the random moves); the games are played
    side by side, each player searching all its positions of a turn together.
    """
    from policylab.games.arena import play_side_by_side

    rng = np.random.default_rng(seed)
    starts: list[GameState] = []
    for _ in range(games):
        s = game.initial()
        for _ in range(2):
            s = s.play(int(rng.choice(s.legal_actions())))
        starts.append(s)
    colours = [i % 2 for i in range(games)]
    ends = play_side_by_side(starts, a, b, colours)
    return sum((s.outcome(c) + 1) / 2 for s, c in zip(ends, colours, strict=True)) / games


# ---------------------------------------------------------------- training loop


def train_alphazero(
    game: str | Game,
    run_dir: str | Path | RunFolder,
    config: AlphaZeroConfig | None = None,
    *,
    resume: bool = False,
    iterations: int | None = None,
    workers: int | None = None,
    backend: str | None = None,
    ray_address: str | None = None,
    on_iteration: Callable[[int, int, dict[str, float]], None] | None = None,
) -> AlphaZeroPlayer:
    """Train AlphaZero into ``run_dir``: a checkpoint and a log row after every iteration.

    The self-play games are the same whatever ``workers`` and ``backend`` are, so a run
    may continue on other workers, or on a Ray cluster, than it started on.

    Args:
        game: The game.
        run_dir: The run folder (refused if it holds a run, unless ``resume``), a path or
            a :class:`~policylab.runs.RunFolder`.
        config: Settings (default: the game's :func:`default_config`; on resume the run's own).
        resume: Continue the run in ``run_dir``.
        iterations: On resume, a new total number of iterations (to train longer).
        workers: Self-play workers instead of the settings' (on resume, the run's).
        backend: ``"processes"`` or ``"ray"`` instead of the settings' (on resume, the run's).
        ray_address: A Ray cluster's address instead of the settings' (on resume, the run's).
        on_iteration: Called with (iteration done, iterations in all, metrics).

    Returns:
        The best network as a player.

    Raises:
        RunFolderError: If the run folder is in use, holds a run (without ``resume``),
            holds none or another learner's (with it).
        TrainingInterrupted: On Ctrl-C or SIGTERM (the checkpoint of the last whole
            iteration is kept); its ``step`` counts the iterations done.
        InvalidArgumentError: A bad setting, an unreachable Ray address (refused within
            seconds, before the run folder is touched) or Ray not installed.
    """
    import torch

    from policylab.deep.common.agent import _TorchThreads
    from policylab.deep.common.checkpoint import load_checkpoint, save_checkpoint, to_numpy_tree
    from policylab.deep.common.logging import RunLogger
    from policylab.games.runs import CHECKPOINT, game_run
    from policylab.runs import RUN_JSON

    g = get_game(game)
    where: dict[str, Any] = {
        k: v
        for k, v in (("workers", workers), ("backend", backend), ("ray_address", ray_address))
        if v is not None
    }
    if where.get("backend", "ray") != "ray":
        where.setdefault("ray_address", None)  # no cluster address for worker processes
    if not resume:
        config = dataclasses.replace(config or default_config(g), **where)
        config.validate()
        check_ray_backend(config)
    elif where.get("backend") == "ray" or ray_address is not None:
        check_ray_backend(_ray_settings(ray_address))
    with (
        game_run(run_dir, resume=resume, algo="alphazero", game=g.name) as run,
        _TorchThreads(1),  # small nets: 1 thread
    ):
        rd = run.path
        resume = run.resume
        if resume:
            meta, tensors = load_checkpoint(rd / CHECKPOINT)
            if meta.get("algo") != "alphazero" or meta.get("game") != g.name:
                raise CheckpointError(f"{str(rd)!r} is not an alphazero run on {g.name}")
            cfg = AlphaZeroConfig(**meta["config"])
            if iterations is not None:
                cfg = dataclasses.replace(cfg, iterations=iterations)
            cfg = dataclasses.replace(cfg, **where)
            done = int(meta["iteration"])
        else:
            assert config is not None  # made above
            cfg = config
            meta, tensors, done = {}, {}, 0
        cfg.validate()
        torch.manual_seed(cfg.seed)
        net = make_network(g, cfg.channels, cfg.blocks)
        best = make_network(g, cfg.channels, cfg.blocks)
        opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        games: list[tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]] = []
        history: list[dict[str, float]] = []
        if resume:
            net.load_state_dict(tensors["net"])
            best.load_state_dict(tensors["best"])
            opt.load_state_dict(tensors["optim"])
            rep = to_numpy_tree(tensors["replay"])
            bounds = np.cumsum(np.concatenate([[0], rep["lengths"]])).astype(int)
            games = [
                (rep["planes"][i:j], rep["pi"][i:j], rep["z"][i:j])
                for i, j in itertools.pairwise(bounds)
            ]
            history = list(meta.get("history", []))
        else:
            best.load_state_dict(net.state_dict())
        syms = symmetries(g)
        pool = _start_workers(cfg)
        try:
            logger = RunLogger(rd, resume_step=done if resume else None)  # cut back to `done`
        except BaseException:
            if pool is not None:
                pool.close(False)
            raise
        finished = False

        def stop_if_interrupted(iterations_done: int) -> None:
            """On Ctrl-C: stop; the checkpoint on disk is that of ``iterations_done``."""
            if run.interrupted:
                raise TrainingInterrupted(iterations_done, str(rd), run.signal or 2)

        def save(iteration: int) -> None:
            lengths = np.array([len(x[2]) for x in games], dtype=np.int64)
            replay = {
                "planes": np.concatenate([x[0] for x in games])
                if games
                else np.zeros((0, 2, g.rows, g.cols), np.float32),
                "pi": np.concatenate([x[1] for x in games])
                if games
                else np.zeros((0, g.n_actions), np.float32),
                "z": np.concatenate([x[2] for x in games]) if games else np.zeros(0, np.float32),
                "lengths": lengths,
            }
            doc = {
                "algo": "alphazero",
                "game": g.name,
                "config": dataclasses.asdict(cfg),
                "iteration": iteration,
                "history": history,
            }
            save_checkpoint(
                rd / CHECKPOINT,
                doc,
                {
                    "net": net.state_dict(),
                    "best": best.state_dict(),
                    "optim": opt.state_dict(),
                    "replay": replay,
                },
            )
            run.write_json(RUN_JSON, {k: v for k, v in doc.items() if k != "history"})

        try:
            with run.catch_interrupts():
                if done == 0:
                    save(0)
                for it in range(done, cfg.iterations):
                    stop_if_interrupted(it)
                    t0 = time.perf_counter()
                    ss = np.random.SeedSequence([cfg.seed, it])
                    seeds = [
                        int(x) for x in ss.generate_state(cfg.games_per_iteration) % (2**31 - 1)
                    ]
                    size = cfg.parallel_games
                    batches = [seeds[i : i + size] for i in range(0, len(seeds), size)]
                    if pool is None:
                        ev = net_evaluator(best)
                        new_games = []
                        for batch in batches:
                            stop_if_interrupted(it)
                            new_games += play_selfplay_games(g, ev, cfg, batch)
                    else:
                        weights = {
                            k: v.detach().numpy().copy() for k, v in best.state_dict().items()
                        }
                        chunks = [batches[i :: cfg.workers] for i in range(cfg.workers)]
                        chunks = [c for c in chunks if c]
                        results = pool.play(
                            (g.name, dataclasses.asdict(cfg), weights),
                            chunks,
                            lambda: stop_if_interrupted(it),  # noqa: B023 (called at once)
                        )
                        by_seed = {
                            s: r
                            for c, res in zip(chunks, results, strict=True)
                            for s, r in zip([s for b in c for s in b], res, strict=True)
                        }
                        new_games = [by_seed[s] for s in seeds]
                    t_play = time.perf_counter() - t0
                    games = (games + new_games)[-cfg.replay_games :]
                    planes = np.concatenate([x[0] for x in games])
                    pis = np.concatenate([x[1] for x in games])
                    zs = np.concatenate([x[2] for x in games])
                    rng = np.random.default_rng(ss.spawn(1)[0])
                    net.train()
                    losses = []
                    for _ in range(cfg.train_steps):
                        stop_if_interrupted(it)
                        idx = rng.integers(len(zs), size=min(cfg.batch_size, len(zs)))
                        x, p, z = planes[idx].copy(), pis[idx].copy(), zs[idx]
                        # a board's symmetric images are as good samples (their policies permuted)
                        which = rng.integers(len(syms), size=len(idx))
                        for j, (turns, mirrored, perm) in enumerate(syms[1:], start=1):
                            sel = which == j
                            x[sel] = transform_board(x[sel], turns, mirrored)
                            p[sel] = p[sel][:, perm]
                        xt, pt, zt = torch.from_numpy(x), torch.from_numpy(p), torch.from_numpy(z)
                        logits, v = net(xt)
                        loss_v = torch.mean((zt - v) ** 2)
                        loss_p = -torch.mean(torch.sum(pt * torch.log_softmax(logits, -1), -1))
                        loss = loss_v + loss_p
                        opt.zero_grad()
                        loss.backward()  # type: ignore[no-untyped-call]
                        opt.step()
                        losses.append((loss_v.item(), loss_p.item()))
                    net.eval()
                    score = 1.0
                    stop_if_interrupted(it)
                    if cfg.eval_games > 0:
                        cand = AlphaZeroPlayer(net, g, cfg.eval_simulations, cfg.c_puct)
                        champ = AlphaZeroPlayer(best, g, cfg.eval_simulations, cfg.c_puct)
                        score = _match(g, cand, champ, cfg.eval_games, int(ss.generate_state(1)[0]))
                    accepted = score >= cfg.accept_score
                    if accepted:
                        best.load_state_dict(net.state_dict())
                    lv, lp = np.mean(losses, axis=0)
                    metrics = {
                        "loss_value": float(lv),
                        "loss_policy": float(lp),
                        "eval_score": float(score),
                        "accepted": float(accepted),
                        "selfplay_positions": float(sum(len(x[2]) for x in new_games)),
                        "selfplay_seconds": t_play,
                        "seconds": time.perf_counter() - t0,
                    }
                    history.append(metrics)
                    save(it + 1)
                    logger.log(it + 1, metrics)
                    if on_iteration is not None:
                        on_iteration(it + 1, cfg.iterations, metrics)
            finished = True
        finally:
            logger.close()
            if pool is not None:  # after Ctrl-C, kill or an error, their games are not waited for
                pool.close(finished)
        return AlphaZeroPlayer(best, g, cfg.eval_simulations, cfg.c_puct, name=str(rd))


def train_alphazero_cli(
    game: Game,
    run: RunFolder,
    seed: int,
    resume: bool,
    fields: dict[str, Any],
    progress: bool,
    console: Console,
) -> None:
    """``policylab train alphazero GAME``: progress bar over iterations and a summary.

    ``run`` (not yet open) is opened once the settings are checked, before any output.
    """
    from rich.progress import Progress

    from policylab.games.runs import game_run

    where: dict[str, Any] = {}
    if resume:
        where = {k: fields.pop(k) for k in RESUME_SETTINGS if k in fields}
        if fields:
            raise InvalidArgumentError(
                "--resume continues a run with its own settings; only --set "
                f"{', '.join(RESUME_SETTINGS)} may change; got {', '.join(sorted(fields))}"
            )
    cfg = None if resume else default_config(game, **{**fields, "seed": seed})
    if cfg is not None:
        check_ray_backend(cfg)  # before the run folder is touched
    elif where.get("backend") == "ray" or where.get("ray_address") is not None:
        check_ray_backend(_ray_settings(where.get("ray_address")))
    t0 = time.perf_counter()
    with (
        game_run(run, resume=resume, algo="alphazero", game=game.name),
        Progress(console=console, disable=not progress) as bar,
    ):
        task = bar.add_task("alphazero", total=None)

        def report(done: int, total: int, m: dict[str, float]) -> None:
            bar.update(task, completed=done, total=total)
            console.print(
                f"iteration {done}/{total}: loss v {m['loss_value']:.3f} p {m['loss_policy']:.3f}, "
                f"new vs best {m['eval_score']:.2f} "
                f"({'accepted' if m['accepted'] else 'kept best'}), "
                f"{m['seconds']:.1f} s"
            )

        train_alphazero(game, run, cfg, resume=resume, on_iteration=report, **where)
    console.print(
        f"alphazero on {game.name}: {time.perf_counter() - t0:.1f} s; run folder {run.path} "
        f"(try `policylab arena {game.name} {run.path} mcts:100`)"
    )
