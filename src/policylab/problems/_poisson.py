"""The Poisson law of the inventory and car-rental problems: probabilities and tails.

SciPy's ``scipy.stats`` takes over a second to import; it is loaded here, when a problem
that needs a Poisson law is built, not by ``import policylab``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["poisson_pmf_and_tail"]


def poisson_pmf_and_tail(n: int, mean: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """P(X = k) and P(X >= k) for k = 0 .. n - 1, X ~ Poisson(``mean``).

    The tail is SciPy's survival function P(X > k - 1), exact far into the tail (not
    1 minus a sum of probabilities).
    """
    from scipy.stats import poisson

    k = np.arange(n)
    dist: Any = poisson(mean)
    return np.asarray(dist.pmf(k), dtype=np.float64), np.asarray(dist.sf(k - 1), dtype=np.float64)
