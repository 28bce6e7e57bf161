"""Loading any saved agent by the algorithm its checkpoint names, and run folders."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from policylab.deep.common.agent import Agent
from policylab.deep.common.checkpoint import load_checkpoint
from policylab.deep.common.envs import EnvLike
from policylab.exceptions import CheckpointError
from policylab.runs import CHECKPOINT

__all__ = ["checkpoint_path", "load", "resume"]


def checkpoint_path(path: str | Path) -> Path:
    """The checkpoint file of ``path``: the file itself, or a run folder's checkpoint.pt.

    Raises:
        CheckpointError: If there is no such file.
    """
    p = Path(path)
    if p.is_dir():
        p = p / CHECKPOINT
    if not p.is_file():
        raise CheckpointError(
            f"no checkpoint at {str(p)!r}; expected a run folder written by `policylab train` "
            "(with checkpoint.pt) or a file written by agent.save()"
        )
    return p


def _agent_class(p: Path) -> type[Agent]:
    from policylab.deep.zoo import ALGORITHMS

    meta: dict[str, Any] = load_checkpoint(p)[0]
    algo = meta.get("algo")
    if algo not in ALGORITHMS:
        raise CheckpointError(f"{str(p)!r} names an unknown algorithm {algo!r}")
    return ALGORITHMS[algo]


def load(path: str | Path, env: EnvLike | None = None) -> Agent:
    """The agent saved at ``path`` (a checkpoint file or a run folder), whatever its algorithm."""
    p = checkpoint_path(path)
    return _agent_class(p).load(p, env=env)


def resume(run_dir: str | Path, env: EnvLike | None = None) -> Agent:
    """The agent of a run folder, whatever its algorithm, ready to continue the run.

    Like :meth:`Agent.resume <policylab.deep.common.agent.Agent.resume>` of the run's own
    algorithm: ``agent.learn(agent.target_steps, run_dir=run_dir)`` finishes the run.
    """
    p = checkpoint_path(run_dir)
    return _agent_class(p).resume(p.parent, env=env)
