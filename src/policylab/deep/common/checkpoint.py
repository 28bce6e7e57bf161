"""Safe, durable checkpoints: tensors plus a JSON document, written atomically.

A checkpoint is one file written by ``torch.save`` holding only plain data: a JSON
string (algorithm, config, spaces, counters, random states) and nested dicts of
tensors (network and optimizer state). It is read back with
``torch.load(weights_only=True)``, whose unpickler accepts tensors and primitive
containers only, so a file crafted to run code when unpickled is refused
(:class:`~policylab.exceptions.CheckpointError`) instead of executed.

Writes go to a temporary file in the same folder, are flushed and fsync'ed, and then
renamed over the old file (``os.replace`` is atomic on POSIX and Windows), so a crash
at any moment leaves either the previous checkpoint or the new one, never half of one.
"""

from __future__ import annotations

import io
import json
import os
import pickle
import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from policylab.exceptions import CheckpointError
from policylab.runs import atomic_write_bytes

__all__ = [
    "FORMAT",
    "atomic_write_bytes",
    "load_checkpoint",
    "save_checkpoint",
    "to_numpy_tree",
    "to_tensor_tree",
]

FORMAT = "policylab-checkpoint"
VERSION = 1


def to_tensor_tree(x: Any) -> Any:
    """NumPy arrays in nested dicts/lists turned into tensors (everything else kept)."""
    if isinstance(x, np.ndarray):
        return torch.from_numpy(x if x.flags.c_contiguous else x.copy(order="C"))
    if isinstance(x, dict):
        return {k: to_tensor_tree(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return type(x)(to_tensor_tree(v) for v in x)
    return x


def to_numpy_tree(x: Any) -> Any:
    """Inverse of :func:`to_tensor_tree` (tensors back to arrays)."""
    if isinstance(x, torch.Tensor):
        return x.numpy()
    if isinstance(x, dict):
        return {k: to_numpy_tree(v) for k, v in x.items()}
    return x


def save_checkpoint(
    path: str | os.PathLike[str], meta: dict[str, Any], tensors: dict[str, Any]
) -> None:
    """Atomically write a checkpoint: ``meta`` (JSON-able) and ``tensors`` (nested dicts)."""
    buf = io.BytesIO()
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "meta": json.dumps(meta),
        "tensors": to_tensor_tree(tensors),
    }
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read a checkpoint written by :func:`save_checkpoint`: ``(meta, tensors)``.

    Raises:
        CheckpointError: If the file is missing, not a policylab checkpoint, corrupt,
            or holds anything but plain data (a pickle that would run code is refused).
    """
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"no checkpoint file at {str(p)!r}")
    foreign = f"{str(p)!r} is not a policylab checkpoint (corrupt or foreign)"
    if not zipfile.is_zipfile(p):  # torch.save writes a zip archive; anything else is foreign
        raise CheckpointError(foreign)
    try:
        with warnings.catch_warnings():  # torch warns about legacy pickles in long paragraphs
            warnings.simplefilter("ignore")
            doc = torch.load(p, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise CheckpointError(
            f"refusing to load {str(p)!r}: it holds objects other than tensors and plain "
            "data; only files written by policylab's save() are accepted"
        ) from None
    except (RuntimeError, EOFError, zipfile.BadZipFile, OSError, ValueError, KeyError):
        raise CheckpointError(foreign) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CheckpointError(foreign)
    if doc.get("version") != VERSION:
        raise CheckpointError(
            f"{str(p)!r} has checkpoint version {doc.get('version')!r}; "
            f"this policylab reads {VERSION}"
        )
    try:
        meta = json.loads(doc["meta"])
    except (KeyError, TypeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{str(p)!r} has a malformed JSON document: {e}") from None
    tensors = doc.get("tensors")
    if not isinstance(meta, dict) or not isinstance(tensors, dict):
        raise CheckpointError(
            f"{str(p)!r} is malformed: expected a JSON object and a dict of tensors"
        )
    return meta, tensors
