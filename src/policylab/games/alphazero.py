"""AlphaZero (Silver et al., 2017/2018): self-play with PUCT search guided by a policy-value net.

One iteration:

1. **Self-play.** Games of the current best network against itself, in parallel
   worker processes. Each move runs PUCT search from the position: a simulation
   descends by

       a = argmax_a  Q(s, a) + c_puct * P(s, a) * sqrt(N(s)) / (1 + N(s, a)),

   expands the leaf with the network's priors P and scores it with the network's
   value v (a finished game scores its outcome) and backs v up the path, negated
   at each level. Dirichlet noise mixes into the root priors,
   P = (1 - eps) p + eps * Dir(alpha), and the move is sampled from the visit counts
   with temperature 1 for the first moves, then taken greedily. Each position is
   stored with the search policy pi(a) = N(s0, a) / sum_b N(s0, b) and the final
   outcome z for the player to move there.
2. **Training** on minibatches from the replay of recent games (mirrored boards
   added) with the loss  (z - v)^2 - pi . log p  (plus weight decay).
3. **Evaluation**: the trained network plays the best one; it replaces the best if
   it scores at least ``accept_score`` (wins + draws / 2 over games).

The run folder keeps an atomic checkpoint after every iteration (networks,
optimizer, replay, counters) and resumes from it. Ctrl-C or SIGTERM stops at once,
keeping the checkpoint of the last whole iteration, and ends the self-play workers
(which also end by themselves if the training process dies).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import signal
import sys
import time
from collections.abc import Callable
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

MIRROR: dict[str, list[int]] = {
    "tic-tac-toe": [2, 1, 0, 5, 4, 3, 8, 7, 6],
    "connect-four": [6, 5, 4, 3, 2, 1, 0],
}
"""The action each action becomes when the board is mirrored left to right."""


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
        workers: Self-play processes (0: in this process).
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
            temperature_moves=4,
            replay_games=600,
            train_steps=200,
            batch_size=128,
            channels=32,
            blocks=2,
            eval_games=10,
            accept_score=0.5,  # good players draw every game: a draw-level score is enough
            random_openings=0.5,
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


Evaluator = Callable[[GameState], tuple[NDArray[np.float64], float]]


def net_evaluator(net: torch.nn.Module) -> Evaluator:
    """(priors over legal moves, value for the player to move) of a position by ``net``."""
    import torch

    net.eval()

    def evaluate(state: GameState) -> tuple[NDArray[np.float64], float]:
        with torch.inference_mode():
            logits, v = net(torch.from_numpy(state.encode()[None]))
        lg = logits[0].double().numpy()
        mask = state.action_mask().astype(bool)
        lg = np.where(mask, lg, -np.inf)
        p = np.exp(lg - lg.max())
        return p / p.sum(), float(v[0])

    return evaluate


# ---------------------------------------------------------------- PUCT search


class _Node:
    __slots__ = ("children", "expanded", "n", "p", "state", "w")

    def __init__(self, state: GameState) -> None:
        self.state = state
        self.expanded = False
        k = state.game.n_actions
        self.p = np.zeros(k)
        self.n = np.zeros(k)
        self.w = np.zeros(k)
        self.children: dict[int, _Node] = {}


class PUCT:
    """AlphaZero's tree search: PUCT selection, network priors and values at the leaves."""

    def __init__(self, evaluate: Evaluator, simulations: int, c_puct: float = 1.5) -> None:
        if simulations < 1:
            raise InvalidArgumentError(f"PUCT needs at least one simulation; got {simulations}")
        self.evaluate = evaluate
        self.simulations = simulations
        self.c_puct = c_puct

    def _expand(self, node: _Node) -> float:
        s = node.state
        if s.is_terminal():
            return s.outcome(s.player)
        p, v = self.evaluate(s)
        node.p = p
        node.expanded = True
        return v

    def visit_counts(
        self,
        state: GameState,
        noise: tuple[float, float] | None = None,
        rng: np.random.Generator | None = None,
    ) -> NDArray[np.float64]:
        """N(s0, a) after the search; ``noise`` = (alpha, eps) mixes Dirichlet noise into P(s0)."""
        root = _Node(state)
        self._expand(root)
        legal = np.array(state.legal_actions())
        if noise is not None and rng is not None:
            alpha, eps = noise
            d = rng.dirichlet([alpha] * len(legal))
            root.p[legal] = (1 - eps) * root.p[legal] + eps * d
        for _ in range(self.simulations):
            node = root
            path: list[tuple[_Node, int]] = []
            while node.expanded:
                s = node.state
                acts = np.array(s.legal_actions())
                q = np.where(node.n[acts] > 0, node.w[acts] / np.maximum(node.n[acts], 1), 0.0)
                u = (
                    self.c_puct
                    * node.p[acts]
                    * math.sqrt(max(node.n.sum(), 1.0))
                    / (1 + node.n[acts])
                )
                a = int(acts[int(np.argmax(q + u))])
                path.append((node, a))
                child = node.children.get(a)
                if child is None:
                    child = _Node(s._apply(a))
                    node.children[a] = child
                    node = child
                    break
                node = child
            value = self._expand(node) if not node.expanded else 0.0
            # value is for the player to move at the leaf; each edge stores it for the mover
            for parent, a in reversed(path):
                value = -value
                parent.n[a] += 1
                parent.w[a] += value
        return root.n.copy()


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
        from policylab.deep.common.agent import _TorchThreads

        with _TorchThreads(1):
            return int(np.argmax(self.search.visit_counts(state)))

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


def play_selfplay_game(
    game: Game, evaluate: Evaluator, cfg: AlphaZeroConfig, seed: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """One self-play game: (planes, search policies, outcomes for the player to move)."""
    rng = np.random.default_rng(seed)
    search = PUCT(evaluate, cfg.simulations, cfg.c_puct)
    s = game.initial()
    if rng.random() < cfg.random_openings:
        for _ in range(2):
            s = s.play(int(rng.choice(s.legal_actions())))
    planes, pis, players = [], [], []
    while not s.is_terminal():
        counts = search.visit_counts(s, (cfg.dirichlet_alpha, cfg.noise_fraction), rng)
        pi = counts / counts.sum()
        planes.append(s.encode())
        pis.append(pi.astype(np.float32))
        players.append(s.player)
        if len(s.moves) < cfg.temperature_moves:
            a = int(rng.choice(len(pi), p=pi))
        else:
            best = np.flatnonzero(counts == counts.max())
            a = int(best[rng.integers(len(best))])
        s = s.play(a)
    z = np.array([s.outcome(p) for p in players], dtype=np.float32)
    return np.stack(planes), np.stack(pis), z


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
    game_name: str, cfg_dict: dict[str, Any], weights: dict[str, NDArray[Any]], seeds: list[int]
) -> list[tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]]:
    import torch

    torch.set_num_threads(1)
    game = get_game(game_name)
    cfg = AlphaZeroConfig(**cfg_dict)
    net = make_network(game, cfg.channels, cfg.blocks)
    net.load_state_dict({k: torch.from_numpy(v) for k, v in weights.items()})
    ev = net_evaluator(net)
    return [play_selfplay_game(game, ev, cfg, s) for s in seeds]


def _match(game: Game, a: AlphaZeroPlayer, b: AlphaZeroPlayer, games: int, seed: int) -> float:
    """A's score (wins + draws / 2 per game); the first two moves of each game are random."""
    rng = np.random.default_rng(seed)
    score = 0.0
    for i in range(games):
        s = game.initial()
        for _ in range(2):
            s = s.play(int(rng.choice(s.legal_actions())))
        first = (a, b) if i % 2 == 0 else (b, a)
        offset = len(s.moves)
        while not s.is_terminal():
            s = s.play(first[(len(s.moves) - offset) % 2].choose(s))
        a_player = offset % 2 if i % 2 == 0 else 1 - offset % 2
        score += (s.outcome(a_player) + 1) / 2
    return score / games


# ---------------------------------------------------------------- training loop


def train_alphazero(
    game: str | Game,
    run_dir: str | Path | RunFolder,
    config: AlphaZeroConfig | None = None,
    *,
    resume: bool = False,
    iterations: int | None = None,
    on_iteration: Callable[[int, int, dict[str, float]], None] | None = None,
) -> AlphaZeroPlayer:
    """Train AlphaZero into ``run_dir``: a checkpoint and a log row after every iteration.

    Args:
        game: The game.
        run_dir: The run folder (refused if it holds a run, unless ``resume``), a path or
            a :class:`~policylab.runs.RunFolder`.
        config: Settings (default: the game's :func:`default_config`; on resume the run's own).
        resume: Continue the run in ``run_dir``.
        iterations: On resume, a new total number of iterations (to train longer).
        on_iteration: Called with (iteration done, iterations in all, metrics).

    Returns:
        The best network as a player.

    Raises:
        RunFolderError: If the run folder is in use, holds a run (without ``resume``),
            holds none or another learner's (with it).
        TrainingInterrupted: On Ctrl-C or SIGTERM (the checkpoint of the last whole
            iteration is kept); its ``step`` counts the iterations done.
    """
    import torch

    from policylab.deep.common.agent import _TorchThreads
    from policylab.deep.common.checkpoint import load_checkpoint, save_checkpoint, to_numpy_tree
    from policylab.deep.common.logging import RunLogger
    from policylab.games.runs import CHECKPOINT, game_run
    from policylab.runs import RUN_JSON

    g = get_game(game)
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
            done = int(meta["iteration"])
        else:
            cfg = config or default_config(g)
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
        mirror = np.array(MIRROR[g.name])
        logger = RunLogger(rd, resume_step=done if resume else None)  # cut back to `done`
        pool = (
            get_context("spawn").Pool(cfg.workers, _worker_init, (os.getpid(),))
            if cfg.workers > 0
            else None
        )
        worker_pids = {p.pid for p in active_children()} if pool is not None else set()
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
                    if pool is None:
                        ev = net_evaluator(best)
                        new_games = []
                        for s in seeds:
                            stop_if_interrupted(it)
                            new_games.append(play_selfplay_game(g, ev, cfg, s))
                    else:
                        weights = {
                            k: v.detach().numpy().copy() for k, v in best.state_dict().items()
                        }
                        chunks = [seeds[i :: cfg.workers] for i in range(cfg.workers)]
                        chunks = [c for c in chunks if c]
                        pending = [
                            pool.apply_async(
                                _worker_games, (g.name, dataclasses.asdict(cfg), weights, c)
                            )
                            for c in chunks
                        ]
                        for r in pending:
                            while not r.ready():  # a signal is seen within a tenth of a second
                                stop_if_interrupted(it)
                                if not worker_pids <= {p.pid for p in active_children()}:
                                    raise RuntimeError(  # the pool would wait for it forever
                                        "a self-play worker process died (killed, or out of "
                                        "memory); the last checkpoint is kept: continue with "
                                        "--resume"
                                    )
                                r.wait(0.1)
                        by_seed = {
                            s: r
                            for c, p in zip(chunks, [r.get() for r in pending], strict=True)
                            for s, r in zip(c, p, strict=True)
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
                        flip = rng.random(len(idx)) < 0.5  # the mirrored board is as good a sample
                        x[flip] = x[flip][..., ::-1]
                        p[flip] = p[flip][:, mirror]
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
            if pool is not None:
                if finished:
                    pool.close()
                else:  # Ctrl-C, kill or an error: the workers' games are not waited for
                    pool.terminate()
                pool.join()
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

    iterations = fields.pop("iterations", None) if resume else None
    if resume and fields:
        raise InvalidArgumentError(
            "--resume continues a run with its own settings; only --set iterations=N may change"
        )
    cfg = None if resume else default_config(game, **{**fields, "seed": seed})
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

        train_alphazero(game, run, cfg, resume=resume, iterations=iterations, on_iteration=report)
    console.print(
        f"alphazero on {game.name}: {time.perf_counter() - t0:.1f} s; run folder {run.path} "
        f"(try `policylab arena {game.name} {run.path} mcts:100`)"
    )
