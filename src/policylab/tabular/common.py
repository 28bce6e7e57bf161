"""What every tabular learner shares: checks, checkpoints, error recorder, progress.

Also the general path over a Gymnasium env: :func:`as_env` (the checked env),
:func:`env_name`, the observation index :class:`StateIndex` and :class:`GymStepper`
(the env behind the kernels' ``env_reset`` / ``env_step``).

A learner's body reads top to bottom as (see :mod:`policylab.tabular.mc`)::

    episodes = check_episodes(episodes)
    ckpts = checkpoint_episodes(episodes, checkpoints)
    rec = Recorder(truth, ckpts)              # truth: GroundTruth or None
    with progress_bar(progress, episodes, "mc-control") as advance:
        for k0, k1 in rec.chunks():           # run episodes k0..k1-1, then record
            ... kernel or Python loop ...
            rec.record(k1, q, v)
            advance(k1 - k0)
    return LearnResult(..., **rec.arrays())
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Hashable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from policylab import validation
from policylab.exceptions import InvalidArgumentError, UnknownLabelError
from policylab.validation import check_count, check_fraction

if TYPE_CHECKING:
    from numpy.typing import NDArray

    from policylab.mdp.finite import FiniteMDP
    from policylab.tabular.truth import GroundTruth

__all__ = [
    "GymStepper",
    "Recorder",
    "StateIndex",
    "as_env",
    "check_count",
    "check_episodes",
    "check_fraction",
    "check_gamma",
    "checkpoint_episodes",
    "env_name",
    "is_finite_mdp",
    "progress_bar",
    "progress_columns",
    "run_seeds",
    "start_state",
]

MAX_EPISODES = 2**62
"""Most episodes (or steps per episode) one learner call accepts: the compiled kernels
count in 64-bit integers."""


def check_episodes(episodes: Any, what: str = "episodes") -> int:
    """A positive integer number of episodes, or an InvalidArgumentError."""
    return check_count(episodes, what, maximum=MAX_EPISODES)


def check_gamma(gamma: Any, default: float) -> float:
    """Gamma in [0, 1] (None: the problem's own)."""
    return validation.check_gamma(gamma, default)


def checkpoint_episodes(episodes: int, checkpoints: int = 50) -> NDArray[np.int64]:
    """Episode counts at which the error is recorded.

    About ``checkpoints`` of them, spaced evenly on a log scale from 1 to ``episodes``
    (always ending at ``episodes``).
    """
    checkpoints = check_count(checkpoints, "checkpoints")
    pts = np.unique(np.geomspace(1, episodes, num=int(checkpoints)).round().astype(np.int64))
    pts = pts[(pts >= 1) & (pts <= episodes)]
    if len(pts) == 0 or pts[-1] != episodes:
        pts = np.append(pts, episodes)
    return pts


def is_finite_mdp(problem: Any) -> bool:
    """Whether a learner's ``problem`` takes the fast path (a FiniteMDP)."""
    from policylab.mdp.finite import FiniteMDP

    return isinstance(problem, FiniteMDP)


def as_env(problem: Any) -> Any:
    """The Gymnasium env of a learner's general path, checked.

    Args:
        problem: A Gymnasium env, or a registered Gymnasium id (``"FrozenLake-v1"``),
            which is made with ``gymnasium.make``.

    Returns:
        The env.

    Raises:
        InvalidArgumentError: If ``problem`` has no ``reset``/``step`` or its action
            space is not ``Discrete``.
    """
    import gymnasium as gym
    from gymnasium import spaces

    env = gym.make(problem) if isinstance(problem, str) else problem
    if not hasattr(env, "reset") or not hasattr(env, "step"):
        raise InvalidArgumentError(
            f"problem must be a FiniteMDP or a Gymnasium env; got {type(problem).__name__}"
        )
    if not isinstance(env.action_space, spaces.Discrete):
        raise InvalidArgumentError(
            f"tabular learners need a Discrete action space; got {env.action_space}"
        )
    return env


def env_name(env: Any) -> str:
    """A display name of an env: its Gymnasium id if registered, else its class name."""
    spec = getattr(env, "spec", None)
    return str(getattr(spec, "id", None) or type(getattr(env, "unwrapped", env)).__name__)


def start_state(mdp: FiniteMDP, start: Hashable | None) -> NDArray[np.float64]:
    """The start distribution: the MDP's own, or all mass on the labelled state ``start``."""
    if start is None:
        return np.ascontiguousarray(mdp.initial, dtype=np.float64)
    s = mdp.state_index(start)
    if mdp.terminal[s]:
        raise InvalidArgumentError(f"cannot start in terminal state {start!r}")
    init = np.zeros(mdp.n_states)
    init[s] = 1.0
    return init


class Recorder:
    """Records the error against the ground truth at checkpoint episodes.

    Args:
        truth: The exact answer, or None (then only the checkpoints drive the chunks).
        checkpoints: Increasing episode counts (from :func:`checkpoint_episodes`).
    """

    def __init__(self, truth: GroundTruth | None, checkpoints: NDArray[np.int64]) -> None:
        self.truth = truth
        self.checkpoints = np.asarray(checkpoints, dtype=np.int64)
        self._max: list[float] = []
        self._rms: list[float] = []
        self._opt: list[float] = []

    def chunks(self) -> Iterator[tuple[int, int]]:
        """``(k0, k1)``: run episodes k0..k1-1, then record at k1 (one per checkpoint)."""
        k0 = 0
        for k1 in self.checkpoints:
            yield k0, int(k1)
            k0 = int(k1)

    def record(
        self,
        q: NDArray[np.float64] | None,
        v: NDArray[np.float64] | None,
        seen: NDArray[np.bool_] | None = None,
    ) -> None:
        """Score the current estimate (no-op without truth)."""
        if self.truth is None:
            return
        e_max, e_rms, share = self.truth.errors(q, v, seen)
        self._max.append(e_max)
        self._rms.append(e_rms)
        self._opt.append(share)

    def arrays(self) -> dict[str, Any]:
        """The ``LearnResult`` fields of the error curve."""
        if self.truth is None:
            return {"checkpoints": np.zeros(0, dtype=np.int64), "error_target": None}
        n = len(self._max)
        return {
            "checkpoints": self.checkpoints[:n].copy(),
            "error_max": np.asarray(self._max),
            "error_rms": np.asarray(self._rms),
            "optimal_actions": np.asarray(self._opt),
            "error_target": self.truth.target,
        }


def progress_columns(unit: str | None = "episodes") -> tuple[Any, ...]:
    """The columns of every policylab progress bar, made to fit a terminal of 80 columns.

    On a narrow terminal the description gives way (cut with an ellipsis) and the bar
    shrinks; the count (``n/total unit``, or a percentage when ``unit`` is None) and the
    elapsed and remaining times keep their full width.
    """
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TaskProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.table import Column

    count: tuple[Any, ...] = (
        (MofNCompleteColumn(), TextColumn(unit)) if unit else (TaskProgressColumn(),)
    )
    return (
        TextColumn(
            "{task.description}",
            table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis", min_width=6),
        ),
        BarColumn(bar_width=None, table_column=Column(ratio=2)),
        *count,
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )


@contextlib.contextmanager
def progress_bar(enabled: bool, total: int, description: str) -> Iterator[Callable[[int], None]]:
    """A rich progress bar over episodes (to stderr); yields ``advance(n)``."""
    if not enabled:
        yield lambda n: None
        return
    from rich.console import Console
    from rich.progress import Progress

    with Progress(
        *progress_columns("episodes"),
        console=Console(stderr=True),
        transient=True,
        expand=True,
    ) as prog:
        task = prog.add_task(description, total=total)
        yield lambda n: prog.advance(task, n)


def _normalize(obs: Any) -> Hashable:
    """An observation as a hashable key: NumPy scalars to Python numbers, arrays to tuples."""
    if isinstance(obs, np.ndarray):
        return tuple(_normalize(x) for x in obs.tolist()) if obs.ndim else _normalize(obs.item())
    if isinstance(obs, (np.integer, np.bool_)):
        return int(obs)
    if isinstance(obs, np.floating):
        return float(obs)
    if isinstance(obs, (tuple, list)):
        return tuple(_normalize(x) for x in obs)
    return obs  # type: ignore[no-any-return]


class StateIndex:
    """Maps a Gymnasium env's observations to rows of the tables (the general path).

    Three kinds: ``StateIndex.discrete(n)`` for ``Discrete(n)`` observations (row =
    the observation), ``StateIndex.of_labels(labels)`` for a fixed list of hashable
    labels (for example a FiniteMDP's ``states``, so that the tables line up with its
    exact values), and ``StateIndex.growing()``, which numbers new observations as they
    come (Blackjack's tuples without a model).
    """

    def __init__(self, labels: Sequence[Hashable] | None, n: int | None, fixed: bool) -> None:
        self._labels: list[Hashable] = list(labels) if labels is not None else []
        self._index: dict[Hashable, int] = {lab: i for i, lab in enumerate(self._labels)}
        self._n = n
        self.fixed = fixed

    @classmethod
    def discrete(cls, n: int) -> StateIndex:
        """Observations are the integers 0..n-1."""
        return cls(None, int(n), True)

    @classmethod
    def of_labels(cls, labels: Sequence[Hashable]) -> StateIndex:
        """Observations are these labels (an unknown observation raises)."""
        return cls(labels, None, True)

    @classmethod
    def growing(cls) -> StateIndex:
        """Observations are numbered in order of first appearance."""
        return cls(None, None, False)

    @classmethod
    def for_env(cls, env: Any) -> StateIndex:
        """The natural index of an env: ``discrete`` for Discrete spaces, else ``growing``."""
        from gymnasium import spaces

        space = getattr(env, "observation_space", None)
        if isinstance(space, spaces.Discrete):
            if int(space.start) != 0:
                return cls.growing()
            return cls.discrete(int(space.n))
        return cls.growing()

    def __len__(self) -> int:
        return self._n if self._n is not None else len(self._labels)

    @property
    def labels(self) -> tuple[Hashable, ...]:
        """The label of each row."""
        if self._n is not None:
            return tuple(range(self._n))
        return tuple(self._labels)

    def __call__(self, obs: Any) -> int:
        """The row of an observation (a new row for a new one, if growing)."""
        if self._n is not None:
            i = int(obs)
            if not 0 <= i < self._n:
                raise InvalidArgumentError(f"observation {obs!r} is outside Discrete({self._n})")
            return i
        key = _normalize(obs)
        try:
            return self._index[key]
        except KeyError:
            if self.fixed:
                raise UnknownLabelError(
                    f"observation {key!r} is not one of the {len(self._labels)} known states"
                ) from None
        except TypeError:
            raise InvalidArgumentError(
                f"observation {obs!r} is not hashable; the general tabular path needs discrete "
                "or hashable observations"
            ) from None
        self._index[key] = len(self._labels)
        self._labels.append(key)
        return len(self._labels) - 1


class GymStepper:
    """A Gymnasium env seen through the kernels' two calls (the general path).

    :func:`~policylab.tabular.kernels.env_reset` and
    :func:`~policylab.tabular.kernels.env_step` call :meth:`reset` and :meth:`step`
    when a kernel runs as plain Python. Observations become table rows through
    ``index`` (a :class:`StateIndex` with a fixed size). The first :meth:`reset` seeds
    the env with ``env_seed``; later resets continue its stream.

    Args:
        env: The Gymnasium env.
        index: Its observations' rows.
        env_seed: Seed of the first ``env.reset`` (None: unseeded).
    """

    def __init__(self, env: Any, index: StateIndex, env_seed: int | None) -> None:
        self.env = env
        self.index = index
        self._seed = env_seed

    def reset(self) -> int:
        """Start an episode; return the row of S_0."""
        obs, _ = self.env.reset(seed=self._seed)
        self._seed = None
        return int(self.index(obs))

    def step(self, a: int) -> tuple[int, float, bool, bool]:
        """Take A_t; return (row of S_{t+1}, R_{t+1}, terminated, truncated).

        A terminal observation that is not one of the index's states (Blackjack-v1's
        final hands) gets row 0: no update ever reads the value of a terminal state.
        """
        obs, r, terminated, truncated, _ = self.env.step(int(a))
        try:
            row = int(self.index(obs))
        except UnknownLabelError:
            if not terminated:
                raise
            row = 0
        return row, float(r), bool(terminated), bool(truncated)


def grow_rows(arr: NDArray[Any], n: int, fill: Any = 0) -> NDArray[Any]:
    """``arr`` with at least ``n`` rows (capacity doubles; new rows hold ``fill``)."""
    if arr.shape[0] >= n:
        return arr
    new = np.full((max(n, 2 * arr.shape[0]), *arr.shape[1:]), fill, dtype=arr.dtype)
    new[: arr.shape[0]] = arr
    return new


def run_seeds(
    learner: Callable[..., Any],
    problem: Any,
    seeds: Sequence[int] | int,
    *,
    workers: int | None = None,
    **kwargs: Any,
) -> list[Any]:
    """Run a tabular learner once per seed, several runs at once.

    The compiled kernels release the GIL (``nogil=True``), so the runs go on threads and
    use several cores; each run is exactly the run ``learner(problem, seed=seed,
    **kwargs)`` would give alone. The list of results is what figures of the mean error
    with a band over seeds take (``save_learning_figure({"MC": results}, path)``).

    Args:
        learner: A registered learner function (``mc_control``, ...).
        problem: Its problem (a FiniteMDP; a Gymnasium env is not shared between threads,
            so pass a FiniteMDP or run env-based learners one at a time).
        seeds: The seeds, or a number n for seeds 0..n-1.
        workers: Threads (default: the number of CPUs, at most the number of seeds).
        **kwargs: Passed to the learner.

    Returns:
        One result per seed, in the order of ``seeds``.
    """
    import os
    from concurrent.futures import ThreadPoolExecutor

    if not is_finite_mdp(problem):
        raise InvalidArgumentError(
            "run_seeds runs several seeds at once on a FiniteMDP; an env cannot be shared "
            "between threads (loop over seeds instead)"
        )
    seed_list = (
        list(range(check_episodes(seeds, "seeds"))) if isinstance(seeds, int) else list(seeds)
    )
    if not seed_list:
        raise InvalidArgumentError("seeds must not be empty")
    n = min(len(seed_list), workers or os.cpu_count() or 1)
    if n <= 1:
        return [learner(problem, seed=s, **kwargs) for s in seed_list]
    with ThreadPoolExecutor(max_workers=n) as pool:
        return list(pool.map(lambda s: learner(problem, seed=s, **kwargs), seed_list))
