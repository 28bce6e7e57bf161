"""What every deep agent shares: envs, seeding, the training loop, predict, save/load, resume.

An algorithm subclasses :class:`Agent` and writes four things: ``_build`` (networks and
optimizer), ``_iteration`` (collect experience and update, returning metrics),
``_act`` (actions for a batch of prepared observations) and the state it adds to a
checkpoint. The loop, logging, progress bar, checkpoints and episode bookkeeping live
here once.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import VectorEnv
from numpy.typing import NDArray

from policylab.deep.common.checkpoint import (
    load_checkpoint,
    save_checkpoint,
    to_numpy_tree,
)
from policylab.deep.common.config import check, config_from_dict, option
from policylab.deep.common.envs import (
    EnvLike,
    env_id_of,
    make_vec_env,
    space_from_json,
    space_to_json,
)
from policylab.deep.common.logging import RunLogger, TrainingProgress
from policylab.deep.common.networks import activation
from policylab.deep.common.normalize import ObservationNormalizer
from policylab.deep.common.walking import resume_env, reward_description
from policylab.exceptions import CheckpointError, InvalidArgumentError, TrainingInterrupted
from policylab.runs import CHECKPOINT, RUN_JSON, RUN_MARKERS, RunFolder
from policylab.validation import check_count

__all__ = ["Agent", "BaseConfig", "Callback"]

A = TypeVar("A", bound="Agent")
Callback = Callable[["Agent", dict[str, float]], bool | None]
"""Called after every training iteration with the agent and that iteration's metrics;
returning False stops training."""


@dataclasses.dataclass
class BaseConfig:
    """Settings every deep agent has."""

    seed: int = option(
        0, "Seed of every random choice: weights, env resets, exploration, minibatches."
    )
    n_envs: int = option(1, "Number of environments stepped in parallel (a gymnasium.vector env).")
    gamma: float = option(0.99, "Discount rate gamma of the return.")
    learning_rate: float = option(3e-4, "Adam step size (its start value when annealed).")
    hidden: tuple[int, ...] = option((64, 64), "Hidden layer sizes of the MLP networks.")
    activation: str = option("tanh", "Activation of the MLP hidden layers: tanh, relu or elu.")
    normalize_obs: bool = option(False, "Normalise observations by their running mean and std.")
    max_grad_norm: float = option(10.0, "Clip the global gradient norm to this value.")
    torch_threads: int = option(
        1, "Torch CPU threads (1 is fastest for small networks); 0 keeps torch's."
    )
    checkpoint_every: int = option(
        10_000,
        "With a run folder: save a checkpoint every this many steps (0: only at the end "
        "and on Ctrl-C).",
    )
    log_interval: int = option(
        1000, "With a run folder: env steps between rows of progress.csv and TensorBoard points."
    )

    def validate(self) -> None:
        """Raise InvalidArgumentError on values out of range."""
        check(self.n_envs >= 1, f"n_envs must be >= 1; got {self.n_envs}")
        check(0.0 <= self.gamma <= 1.0, f"gamma must be in [0, 1]; got {self.gamma}")
        check(self.learning_rate > 0, f"learning_rate must be > 0; got {self.learning_rate}")
        check(all(h >= 1 for h in self.hidden), f"hidden sizes must be >= 1; got {self.hidden}")
        activation(self.activation)  # raises on an unknown name
        check(self.max_grad_norm > 0, f"max_grad_norm must be > 0; got {self.max_grad_norm}")
        check(self.torch_threads >= 0, f"torch_threads must be >= 0; got {self.torch_threads}")
        check(self.log_interval >= 1, f"log_interval must be >= 1; got {self.log_interval}")
        check(
            self.checkpoint_every >= 0,
            f"checkpoint_every must be >= 0; got {self.checkpoint_every}",
        )


class Agent(ABC):
    """A deep RL agent on a Gymnasium environment.

    Args:
        env: A Gymnasium id (``"CartPole-v1"``), a ``gymnasium.Env``, or a vector env.
        config: A config of the algorithm's class; keyword arguments override its fields.
        **overrides: Config fields by name (``PPO("CartPole-v1", n_envs=8)``).
    """

    algo: ClassVar[str]
    config_class: ClassVar[type[BaseConfig]]
    config: Any

    def __init__(self, env: EnvLike, config: BaseConfig | None = None, **overrides: Any) -> None:
        if config is not None and not isinstance(config, self.config_class):
            raise InvalidArgumentError(
                f"config must be a {self.config_class.__name__}; got {type(config).__name__}"
            )
        self.config = config_from_dict(self.config_class, overrides, base=config)
        self.env_id = env_id_of(env)
        self._envs: VectorEnv | None = make_vec_env(env, self.config.n_envs)
        self._setup(self._envs.single_observation_space, self._envs.single_action_space)

    # ----------------------------------------------------------------- set-up
    def _setup(self, observation_space: gym.Space[Any], action_space: gym.Space[Any]) -> None:
        self.observation_space, self.action_space = observation_space, action_space
        self.num_timesteps = 0
        self.target_steps = 0
        self.n_updates = 0
        self.episodes = 0
        self.recent_returns: deque[float] = deque(maxlen=100)
        self._recent_mean: tuple[Any, float] = (None, 0.0)  # (key, mean) of the above
        self.rng = np.random.default_rng(self.config.seed)
        self.torch_gen = torch.Generator().manual_seed(int(self.rng.integers(2**62)))
        self.obs_normalizer = (
            ObservationNormalizer(tuple(observation_space.shape or ()))
            if self.config.normalize_obs
            else None
        )
        self._obs: NDArray[Any] | None = None
        self._schedule_anchor: tuple[int, float] = (0, 1.0)
        self._run_path: Path | None = None
        with self._threads():
            self._build()

    def _threads(self) -> _TorchThreads:
        return _TorchThreads(self.config.torch_threads)

    @property
    def envs(self) -> VectorEnv:
        """The training vector env (re-made from ``env_id`` for a loaded agent)."""
        if self._envs is None:
            if self.env_id is None:
                raise InvalidArgumentError(
                    "this agent was loaded without an env id; pass env= to load()"
                )
            self._envs = make_vec_env(self.env_id, self.config.n_envs)
        return self._envs

    @abstractmethod
    def _build(self) -> None:
        """Create networks, optimizer and buffers."""

    @abstractmethod
    def _iteration(self) -> dict[str, float]:
        """Collect experience and update once; return this iteration's metrics."""

    @abstractmethod
    def _act(self, obs: torch.Tensor, deterministic: bool) -> NDArray[Any]:
        """Actions (NumPy, env format) for a batch of prepared observations."""

    @abstractmethod
    def _state_tensors(self, training_state: bool) -> dict[str, Any]:
        """Network (and optimizer, if ``training_state``) state for a checkpoint."""

    @abstractmethod
    def _load_state_tensors(self, tensors: dict[str, Any]) -> None:
        """Restore what :meth:`_state_tensors` gave."""

    # ------------------------------------------------------------ env helpers
    def _prepare(self, obs: NDArray[Any], update: bool = False) -> NDArray[Any]:
        """Observations as the networks see them (normalised if configured)."""
        if self.obs_normalizer is not None:
            return self.obs_normalizer(obs, update=update)
        if obs.dtype == np.float64:
            return obs.astype(np.float32)
        return obs

    def _reset_envs(self) -> NDArray[Any]:
        n = self.envs.num_envs
        obs, _ = self.envs.reset(seed=int(self.rng.integers(2**31 - 1)))
        self._ep_return = np.zeros(n)
        self._ep_length = np.zeros(n, dtype=np.int64)
        self._prev_done = np.zeros(n, dtype=bool)
        self._all_valid = np.ones(n, dtype=bool)
        self._obs = np.asarray(obs)
        return self._obs

    def _env_step(
        self, actions: NDArray[Any]
    ) -> tuple[NDArray[Any], NDArray[Any], NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
        """Step the envs; returns (next_obs, rewards, terminated, truncated, valid).

        Under next-step autoreset an env whose episode ended on the previous step only
        resets on this one: ``valid`` is False for it (its step is no transition), and
        its returned observation is the first of its next episode. For an env that ends
        on this step, ``next_obs`` is the last observation of the episode, so a
        truncated step can be bootstrapped from it.
        """
        env_actions = actions
        if isinstance(self.action_space, gym.spaces.Box):
            env_actions = np.clip(actions, self.action_space.low, self.action_space.high)
        next_obs, rew, term, trunc, _ = self.envs.step(env_actions)
        rew = np.asarray(rew, dtype=np.float64)
        term, trunc = np.asarray(term, dtype=bool), np.asarray(trunc, dtype=bool)
        prev_done = self._prev_done
        if prev_done.any():  # the envs that only reset on this step
            valid = ~prev_done
            term, trunc = term & valid, trunc & valid
            self._ep_return[valid] += rew[valid]
            self._ep_length[valid] += 1
            self.num_timesteps += int(valid.sum())
        else:  # every env took a step: whole-array updates
            valid = self._all_valid
            if len(valid) != len(rew):
                valid = self._all_valid = np.ones(len(rew), dtype=bool)
            self._ep_return += rew
            self._ep_length += 1
            self.num_timesteps += len(rew)
        done = term | trunc
        if done.any():
            for i in np.flatnonzero(done):
                self.recent_returns.append(float(self._ep_return[i]))
                self.episodes += 1
            self._ep_return[done] = 0.0
            self._ep_length[done] = 0
        self._prev_done = done
        self._obs = next_obs
        return next_obs, rew, term, trunc, valid

    @property
    def progress_remaining(self) -> float:
        """Fraction of the annealed schedules left: 1 at the start, 0 at ``target_steps``.

        A fresh run goes linearly from 1 to 0 over its ``target_steps``. A run resumed to
        the same target continues exactly where it stopped, so an interrupted and resumed
        run anneals as an uninterrupted one. A run *extended* to a larger target (a second
        ``learn`` with more steps, or ``policylab train --resume --steps MORE``) continues
        from the fraction it had reached and goes linearly to 0 at the new target: an
        annealed learning rate never jumps back up. (A run whose rate has already
        reached 0 therefore cannot learn more by extension; train a new run instead.)
        """
        t0, p0 = self._schedule_anchor
        total = self.target_steps
        if total <= 0:
            return 1.0
        if t0 == 0 and p0 == 1.0:
            return max(0.0, 1.0 - self.num_timesteps / total)
        if total <= t0:
            return 0.0
        return max(0.0, p0 * (total - self.num_timesteps) / (total - t0))

    def recent_mean_return(self) -> float | None:
        """Mean return of the last (up to) 100 training episodes, or None before the first."""
        if not self.recent_returns:
            return None
        key = (self.episodes, len(self.recent_returns), self.recent_returns[-1])
        if self._recent_mean[0] != key:  # computed again only after an episode ends
            self._recent_mean = (key, float(np.mean(self.recent_returns)))
        return self._recent_mean[1]

    # -------------------------------------------------------------- training
    def learn(
        self: A,
        total_steps: int,
        callback: Callback | None = None,
        *,
        progress: bool = False,
        run_dir: str | Path | RunFolder | None = None,
    ) -> A:
        """Train until the agent has taken ``total_steps`` env steps in all.

        A fresh agent trains ``total_steps`` steps; a loaded or resumed agent continues
        from its own step count (see :attr:`progress_remaining` for annealed schedules).

        With a run folder, the folder belongs to this call (a lock: a second process is
        refused), ``run.json``, ``progress.csv`` and TensorBoard events (``tb/``) are
        written, and ``checkpoint.pt`` is saved every ``checkpoint_every`` steps, at the
        end, and on Ctrl-C or SIGTERM, which then raise
        :class:`~policylab.exceptions.TrainingInterrupted` after saving. A folder that
        already holds a run is refused unless it is this agent's own (it came from
        :meth:`resume` of that folder, or an earlier ``learn`` into it); the log is then
        cut back to the checkpoint's step, so it always matches the checkpoint.

        Args:
            total_steps: Env steps (summed over the parallel envs) to train up to,
                counting those already taken.
            callback: Called after every iteration with ``(agent, metrics)``; returning
                False stops training early.
            progress: Draw a rich progress bar with steps/s and the recent return.
            run_dir: A run folder path, or an open :class:`~policylab.runs.RunFolder`.

        Returns:
            The agent itself.

        Raises:
            InvalidArgumentError: If ``total_steps`` is not an integer >= 1 or is below
                the steps already taken.
            RunFolderError: If the run folder is in use or holds another run.
            TrainingInterrupted: On Ctrl-C with a run folder (after saving).
        """
        given: Any = total_steps
        if isinstance(given, float) and given.is_integer():  # 1e5 is a count too
            given = int(given)
        total = check_count(given, "total_steps")
        if total < self.num_timesteps:
            raise InvalidArgumentError(
                f"total_steps {total:,} is below the {self.num_timesteps:,} steps this agent "
                "has already taken (total_steps counts every step of the run)"
            )
        run: RunFolder | None
        if run_dir is None or isinstance(run_dir, RunFolder):
            run = run_dir
        else:
            path = Path(run_dir)
            run = RunFolder(
                path,
                resume=self._run_path is not None and self._run_path == path.resolve(),
                markers=RUN_MARKERS,
                command=f"{self.algo} on {self.env_id}",
            )
        own = run is not None and not run.is_open
        if run is not None and own:
            run.open()
        try:
            interrupted = self._learn(total, callback, progress, run)
        finally:
            if run is not None and own:
                run.close()
        if run is not None:
            self._run_path = run.path.resolve()
            if interrupted:
                raise TrainingInterrupted(self.num_timesteps, str(run.path), run.signal or 2)
        return self

    def _learn(
        self, total: int, callback: Callback | None, progress: bool, run: RunFolder | None
    ) -> bool:
        """The training loop of :meth:`learn`; returns whether Ctrl-C stopped it."""
        if self.target_steps and total != self.target_steps and self.num_timesteps > 0:
            self._schedule_anchor = (self.num_timesteps, self.progress_remaining)
        self.target_steps = total
        logger = None
        if run is not None:
            logger = RunLogger(run.path, resume_step=self.num_timesteps if run.resume else None)
            self._write_run_json(run)
        every = self.config.checkpoint_every
        next_ckpt = (self.num_timesteps // every + 1) * every if every else None
        next_log = self.num_timesteps
        shown = 0.0
        interrupted = False
        try:
            with (
                self._threads(),
                _FlushDenormals(),
                run.catch_interrupts() if run is not None else contextlib.nullcontext(),
                TrainingProgress(
                    self.target_steps,
                    start=self.num_timesteps,
                    enabled=progress,
                    description=self.algo,  # the env is on the start-up line: 80 columns
                ) as bar,
            ):
                if self._obs is None:
                    self._reset_envs()
                while self.num_timesteps < self.target_steps:
                    if run is not None and run.interrupted:
                        interrupted = True
                        break
                    metrics = self._iteration()
                    metrics["episodes"] = float(self.episodes)
                    metrics["recent_return"] = self.recent_mean_return()  # type: ignore[assignment]
                    metrics["steps_per_second"] = bar.steps_per_second(self.num_timesteps)
                    now = time.perf_counter()
                    last = self.num_timesteps >= self.target_steps
                    if now - shown > 0.1 or last:
                        bar.update(self.num_timesteps, metrics["recent_return"])
                        shown = now
                    if logger is not None and (self.num_timesteps >= next_log or last):
                        logger.log(self.num_timesteps, metrics)
                        next_log = self.num_timesteps + self.config.log_interval
                    if (
                        run is not None
                        and next_ckpt is not None
                        and self.num_timesteps >= next_ckpt
                    ):
                        self.save(run.file(CHECKPOINT), training_state=True)
                        next_ckpt = (self.num_timesteps // every + 1) * every
                    if callback is not None and callback(self, metrics) is False:
                        break
                if run is not None:  # inside the block: a Ctrl-C now waits for the save
                    self.save(run.file(CHECKPOINT), training_state=True)
        finally:
            if logger is not None:
                logger.close()
        return interrupted

    def _write_run_json(self, run: RunFolder) -> None:
        doc = {
            "algo": self.algo, "env_id": self.env_id, "total_steps": self.target_steps,
            "config": _jsonable(dataclasses.asdict(self.config)),
            "reward": reward_description(self._envs),
        }  # fmt: skip
        run.write_json(RUN_JSON, doc)

    @classmethod
    def resume(cls: type[A], run_dir: str | Path, env: EnvLike | None = None) -> A:
        """The agent of a run folder, from its last checkpoint, ready to ``learn`` on.

        ``agent.learn(agent.target_steps, run_dir=run_dir)`` finishes the run (the
        folder's log is cut back to the checkpoint's step first); episodes in progress
        at the checkpoint are restarted.
        """
        if env is None:  # a run on the walking reward continues on it
            env = resume_env(run_dir)
        agent = cls.load(Path(run_dir) / CHECKPOINT, env=env)
        agent._run_path = Path(run_dir).resolve()
        return agent

    # ------------------------------------------------------------- acting
    def predict(self, obs: Any, deterministic: bool = True) -> NDArray[Any]:
        """Actions for one observation or a batch of them.

        Args:
            obs: One observation of the env's observation space, or a batch (first axis).
            deterministic: The greedy action (True) or one sampled from the policy.

        Returns:
            One action for one observation, else an array of actions.
        """
        o = np.asarray(obs)
        shape = tuple(self.observation_space.shape or ())
        single = o.shape == shape
        if not single and o.shape[1:] != shape:
            raise InvalidArgumentError(
                f"obs must have shape {shape} (one) or (batch, *{shape}); got {o.shape}"
            )
        batch = o[None] if single else o
        with torch.no_grad(), self._threads():
            actions = self._act(torch.as_tensor(self._prepare(batch)), deterministic)
        return actions[0] if single else actions

    def state_parameters(self) -> list[torch.Tensor]:
        """Every network parameter and buffer of the agent, in a fixed order."""
        return [
            t
            for v in self._state_tensors(False).values()
            for t in v.values()
            if isinstance(t, torch.Tensor)
        ]

    # ---------------------------------------------------------- checkpoints
    def save(self, path: str | Path, *, training_state: bool = False) -> None:
        """Write the agent to ``path`` atomically (a crash leaves the old file intact).

        Args:
            path: The checkpoint file (conventionally ``*.pt``).
            training_state: Also save what continuing training needs beyond the
                weights (optimizer, replay buffer); :meth:`learn` does for run folders.
        """
        meta = {
            "algo": self.algo,
            "env_id": self.env_id,
            "config": _jsonable(dataclasses.asdict(self.config)),
            "observation_space": space_to_json(self.observation_space),
            "action_space": space_to_json(self.action_space),
            "num_timesteps": self.num_timesteps,
            "target_steps": self.target_steps,
            "n_updates": self.n_updates,
            "episodes": self.episodes,
            "recent_returns": list(self.recent_returns),
            "rng_state": self.rng.bit_generator.state,
            "schedule_anchor": list(self._schedule_anchor),
            "training_state": training_state,
        }
        tensors: dict[str, Any] = {"model": self._state_tensors(training_state)}
        tensors["torch_generator"] = self.torch_gen.get_state()
        if self.obs_normalizer is not None:
            tensors["obs_normalizer"] = self.obs_normalizer.rms.state_dict()
        save_checkpoint(path, meta, tensors)

    @classmethod
    def load(cls: type[A], path: str | Path, env: EnvLike | None = None) -> A:
        """An agent from a checkpoint written by :meth:`save`.

        Args:
            path: The checkpoint file.
            env: The env to continue training on; None re-makes it from the saved id
                when needed (``predict`` needs no env).

        Raises:
            CheckpointError: If the file is missing, unsafe, corrupt, or of another algorithm.
        """
        meta, tensors = load_checkpoint(path)
        if meta.get("algo") != cls.algo:
            raise CheckpointError(
                f"{str(path)!r} holds a {meta.get('algo')!r} agent, not {cls.algo!r}"
            )
        try:
            agent = cls.__new__(cls)
            agent.config = config_from_dict(cls.config_class, meta["config"])
            agent.env_id = meta["env_id"] if env is None else env_id_of(env)
            agent._envs = None if env is None else make_vec_env(env, agent.config.n_envs)
            obs_space = space_from_json(meta["observation_space"])
            act_space = space_from_json(meta["action_space"])
        except (KeyError, TypeError, InvalidArgumentError) as e:
            raise CheckpointError(f"{str(path)!r} has a malformed description: {e}") from None
        if agent._envs is not None and (
            agent._envs.single_observation_space.shape != obs_space.shape
            or agent._envs.single_action_space != act_space
        ):
            raise InvalidArgumentError(
                f"env {agent.env_id!r} has spaces {agent._envs.single_observation_space}, "
                f"{agent._envs.single_action_space}; the checkpoint was trained on "
                f"{obs_space}, {act_space}"
            )
        agent._setup(obs_space, act_space)
        try:
            agent._load_state_tensors(tensors["model"])
            agent.torch_gen.set_state(tensors["torch_generator"])
            if agent.obs_normalizer is not None:
                agent.obs_normalizer.rms.load_state_dict(to_numpy_tree(tensors["obs_normalizer"]))
            agent.num_timesteps = int(meta["num_timesteps"])
            agent.target_steps = int(meta["target_steps"])
            agent.n_updates = int(meta["n_updates"])
            agent.episodes = int(meta["episodes"])
            agent.recent_returns.extend(float(x) for x in meta["recent_returns"])
            agent.rng.bit_generator.state = meta["rng_state"]
            t0, p0 = meta.get("schedule_anchor", (0, 1.0))
            agent._schedule_anchor = (int(t0), float(p0))
        except (KeyError, RuntimeError, ValueError, TypeError) as e:
            raise CheckpointError(
                f"{str(path)!r} does not fit a {cls.algo} agent: {type(e).__name__}: {e}"
            ) from None
        return agent


def _jsonable(x: Any) -> Any:
    if isinstance(x, tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    return x


class _TorchThreads:
    """Set torch's CPU thread count for a block, restoring it after (0 leaves it alone)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.old = 0

    def __enter__(self) -> None:
        if self.n:
            self.old = torch.get_num_threads()
            if self.old != self.n:
                torch.set_num_threads(self.n)

    def __exit__(self, *exc: object) -> None:
        if self.n and self.old and self.old != self.n:
            torch.set_num_threads(self.old)


class _FlushDenormals:
    """Treat subnormal floats as zero in this thread's CPU arithmetic for a block.

    Adam's moment estimates of a gradient that stays at zero (a dead ReLU unit, an
    action never taken) decay geometrically into the subnormal range, where x86 CPUs
    take a slow microcode path for every operation on them: on a 256x256 DQN the
    optimizer step became several times slower after a few thousand updates. Flushing
    them to zero (the CPU's flush-to-zero and denormals-are-zero modes) changes only
    numbers below 1.2e-38 in magnitude, which are negligible next to Adam's epsilon
    and never reach the weights. The previous mode is restored on exit.
    """

    def __init__(self) -> None:
        self.was_on = False

    def __enter__(self) -> None:
        # a subnormal times one is zero exactly when the mode is already on
        self.was_on = bool(torch.tensor([1e-39]).mul(1.0).eq(0).item())
        if not self.was_on:
            torch.set_flush_denormal(True)

    def __exit__(self, *exc: object) -> None:
        if not self.was_on:
            torch.set_flush_denormal(False)
