"""Small statistics of rates and rankings: Wilson score intervals and Spearman rank correlation.

The rank correlation is computed here (average ranks for ties, Pearson correlation of the ranks)
with a permutation p-value: exact over every permutation for up to ``EXACT_PERMUTATIONS_UP_TO``
items, otherwise from seeded random permutations. Design sweeps have a handful of designs, where
the usual t approximation of the p-value is poor.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from energy_margin.errors import InvalidParameterError, check_int, check_positive_float, check_positive_int

__all__ = [
    "EXACT_PERMUTATIONS_UP_TO",
    "Z_95",
    "RankCorrelation",
    "rank",
    "spearman",
    "spearman_rho",
    "wilson_interval",
]

#: Two-sided 95 % standard normal quantile.
Z_95 = 1.959963984540054
#: Up to this many items the permutation p-value enumerates every permutation (8! = 40 320).
EXACT_PERMUTATIONS_UP_TO = 8


def wilson_interval(successes: int, trials: int, *, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    Args:
        successes: number of successes k, 0 <= k <= trials.
        trials: number of trials n, >= 1.
        z: standard normal quantile of the interval (1.96 for 95 %).

    Returns:
        ``(low, high)``, both in [0, 1].

    Raises:
        InvalidParameterError: (a ``ValueError``) ``trials`` < 1, ``successes`` outside [0, trials] or
            ``z`` <= 0.

    """
    check_positive_int("trials", trials)
    check_int("successes", successes, minimum=0, maximum=trials)
    check_positive_float("z", z)
    n = float(trials)
    p = successes / n
    denominator = 1.0 + z * z / n
    centre = (p + z * z / (2.0 * n)) / denominator
    half = z / denominator * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n))
    # At no or all successes the bound is exactly 0 or 1 (rounding would leave it 1e-17 away).
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return low, high


def rank(values: np.ndarray) -> np.ndarray:
    """Ranks 1..n of ``values`` (shape (n,)), tied values sharing the average of their ranks."""
    values = np.asarray(values, dtype=float)
    order = np.argsort(values, kind="mergesort")
    ranks = np.empty(values.size, dtype=float)
    ordered = values[order]
    start = 0
    for end in range(1, values.size + 1):
        if end == values.size or ordered[end] != ordered[start]:
            ranks[order[start:end]] = (start + end + 1) / 2.0
            start = end
    return ranks


def _pearson(x: np.ndarray, y: np.ndarray) -> float | None:
    x = x - x.mean()
    y = y - y.mean()
    norm = math.sqrt(float(x @ x) * float(y @ y))
    if norm == 0.0:
        return None
    return float(np.clip((x @ y) / norm, -1.0, 1.0))


@dataclass(frozen=True)
class RankCorrelation:
    """Spearman's rank correlation of two sequences.

    Attributes:
        rho: the correlation in [-1, 1]; ``None`` when either sequence is constant.
        p_value: two-sided permutation p-value of ``rho`` (the share of orderings of the second
            sequence whose |rho| is at least the observed one); ``None`` with ``rho``.
        exact: whether ``p_value`` enumerated every permutation (otherwise random ones).
        n: number of pairs.

    """

    rho: float | None
    p_value: float | None
    exact: bool
    n: int


def spearman_rho(x: np.ndarray, y: np.ndarray) -> float | None:
    """Spearman's rho of ``x`` and ``y`` (shape (n,) each); ``None`` when either is constant."""
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.size != y.size:
        raise InvalidParameterError("x", f"and y must have the same length, got {x.size} and {y.size}")
    if x.size < 2:
        return None
    return _pearson(rank(x), rank(y))


def spearman(x: np.ndarray, y: np.ndarray, *, permutations: int = 20000, seed: int = 0) -> RankCorrelation:
    """Spearman's rank correlation of ``x`` and ``y`` with a two-sided permutation p-value.

    Args:
        x: first sequence, shape (n,).
        y: second sequence, shape (n,).
        permutations: random permutations when n > ``EXACT_PERMUTATIONS_UP_TO``, >= 1.
        seed: seed of those random permutations.

    """
    check_positive_int("permutations", permutations)
    rho = spearman_rho(x, y)
    n = int(np.asarray(x).size)
    exact = n <= EXACT_PERMUTATIONS_UP_TO
    if rho is None:
        return RankCorrelation(None, None, exact, n)
    rx = rank(np.asarray(x, dtype=float).ravel())
    ry = rank(np.asarray(y, dtype=float).ravel())
    rx = (rx - rx.mean()) / np.linalg.norm(rx - rx.mean())
    ry = (ry - ry.mean()) / np.linalg.norm(ry - ry.mean())
    if exact:
        orders = np.array(list(itertools.permutations(range(n))), dtype=int)
    else:
        rng = np.random.default_rng(seed)
        orders = np.array([rng.permutation(n) for _ in range(permutations)], dtype=int)
    null = ry[orders] @ rx
    # A small tolerance so that orderings tying the observed |rho| count despite rounding.
    extreme = int(np.count_nonzero(np.abs(null) >= abs(rho) - 1e-12))
    p_value = extreme / len(orders) if exact else (extreme + 1) / (len(orders) + 1)
    return RankCorrelation(rho, float(p_value), exact, n)
