from __future__ import annotations

import sys
from pathlib import Path

import torch

torch.set_num_threads(1)

# helper modules of this folder (deep_testenvs) import by name under --import-mode=importlib
sys.path.insert(0, str(Path(__file__).resolve().parent))
