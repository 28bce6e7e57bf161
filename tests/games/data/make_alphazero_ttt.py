"""Make ``alphazero_ttt.npz``: the best network of AlphaZero on tic-tac-toe, defaults, seed 0.

Run from the repository root: ``python tests/games/data/make_alphazero_ttt.py`` (about
two minutes on one core). It trains ``policylab train alphazero tic-tac-toe`` with the
default settings into a temporary folder and keeps the best network's weights, which
``tests/games/test_alphazero.py`` checks against every line of perfect play.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from policylab.deep.common.checkpoint import load_checkpoint
from policylab.games.alphazero import default_config, train_alphazero

OUT = Path(__file__).with_name("alphazero_ttt.npz")

if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "az"
        train_alphazero("tic-tac-toe", run, default_config("tic-tac-toe", seed=0))
        _, tensors = load_checkpoint(run / "checkpoint.pt")
    np.savez_compressed(OUT, **{k: v.numpy() for k, v in tensors["best"].items()})
    print(f"wrote {OUT}")
