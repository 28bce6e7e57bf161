"""Narrow and outer matrix products: the plain product against the MLP passes' ``_mm``.

The products of a one-output layer, a Q-head over a few actions, the action columns of
dL/dx and the step back through a one-output layer, timed alone on one core (median
wall-clock microseconds of 300 calls each, after 20 to warm up), first as
``torch.matmul`` and then through ``policylab.deep.common.mlp_grad._mm``, which computes
a narrow result as the wide one, (b^T a^T)^T, and an outer product as a broadcast
multiplication:

    taskset -c 1 python benchmarks/narrow_products.py
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import torch

from policylab.deep.common.mlp_grad import _mm

# (stacked networks or None, rows, inner, columns): SAC/TD3 critics and actor heads,
# DQN and PPO heads, and a grid of narrow shapes
SHAPES = [
    (2, 256, 257, 1), (2, 256, 1, 257), (2, 256, 256, 6), (None, 512, 257, 12),
    *[(None, r, k, n) for r in (64, 128, 256, 512) for k in (65, 257, 401) for n in (2, 4, 6, 12)],
]  # fmt: skip


def _median_us(fn: Callable[[], object], calls: int = 300) -> float:
    for _ in range(20):
        fn()
    times = []
    for _ in range(calls):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e6 * float(np.median(times))


def main() -> None:
    """Print one table row per shape: plain and ``_mm`` microseconds and their ratio."""
    torch.set_num_threads(1)
    print("| stacked | rows | inner | columns | matmul us | _mm us | matmul / _mm |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for k, rows, inner, cols in SHAPES:
        stack = () if k is None else (k,)
        a = torch.randn(*stack, rows, inner)
        # b as the parameter blocks hold it: columns of a wider matrix (a strided view)
        b = torch.randn(*stack, inner, 2 * cols)[..., :cols]
        plain = _median_us(lambda a=a, b=b: torch.matmul(a, b))
        ours = _median_us(lambda a=a, b=b: _mm(a, b))
        print(
            f"| {k or ''} | {rows} | {inner} | {cols} | {plain:.1f} | {ours:.1f} "
            f"| {plain / ours:.2f}x |"
        )


if __name__ == "__main__":
    main()
