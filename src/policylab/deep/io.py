"""Loading any saved agent by the algorithm its checkpoint names, and run folders."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from policylab.deep.common.agent import CHECKPOINT, Agent
from policylab.deep.common.checkpoint import load_checkpoint
from policylab.deep.common.envs import EnvLike
from policylab.exceptions import CheckpointError

__all__ = ["checkpoint_path", "load"]


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


def load(path: str | Path, env: EnvLike | None = None) -> Agent:
    """The agent saved at ``path`` (a checkpoint file or a run folder), whatever its algorithm."""
    from policylab.deep.zoo import ALGORITHMS

    p = checkpoint_path(path)
    meta: dict[str, Any] = load_checkpoint(p)[0]
    algo = meta.get("algo")
    if algo not in ALGORITHMS:
        raise CheckpointError(f"{str(p)!r} names an unknown algorithm {algo!r}")
    return ALGORITHMS[algo].load(p, env=env)
