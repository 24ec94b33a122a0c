"""The Wilcoxon signed-rank test on paired differences, zero differences dropped.

GENEA's side-by-side analysis compares two systems by the differences of their ratings
on the same pages. The test here follows Wilcoxon's own handling of zeros (a page rating
both systems alike carries no sign and is left out) and chooses its p-value as follows:

- with at most 50 non-zero differences and no tied magnitudes, the exact null
  distribution of the positive rank sum (every sign pattern equally likely), counted by
  dynamic programming over the ranks;
- otherwise the normal approximation with the tie correction of the variance,
  ``z = (T - n(n+1)/4) / sqrt(n(n+1)(2n+1)/24 - sum(t^3 - t)/48)``; with ``continuity``
  the numerator moves half a unit towards zero, as R's ``wilcox.test`` does by default
  (scipy's ``correction=True``); without it, as scipy does by default.

Two-sided p = min(1, 2 P(T <= min(T+, T-))). The tests check both branches against
scipy.stats.wilcoxon (``method="exact"`` and ``method="asymptotic"``, with and without
``correction``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats as sps

EXACT_UP_TO = 50


@dataclass(frozen=True)
class SignedRankResult:
    n_nonzero: int
    statistic: float  # min(T+, T-), as scipy reports it for a two-sided test
    positive_rank_sum: float  # T+: which way the differences lean
    p: float
    method: str  # "exact", "normal" or "normal, continuity-corrected"


@lru_cache(maxsize=None)
def _rank_sum_cdf(n: int) -> np.ndarray:
    """P(T+ <= t) for t = 0 .. n(n+1)/2 under the null, by counting sign patterns."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for rank in range(1, n + 1):
        counts[rank:] = counts[rank:] + counts[:-rank].copy()
    return np.cumsum(counts) / 2.0**n


def signed_rank_test(differences, continuity: bool = False) -> SignedRankResult:
    """Two-sided Wilcoxon signed-rank test of ``differences`` being symmetric about zero;
    ``continuity`` corrects the normal approximation by half a unit."""
    d = np.asarray(differences, dtype=np.float64)
    d = d[d != 0]
    n = len(d)
    if n == 0:
        return SignedRankResult(0, np.nan, 0.0, np.nan, "not computed")
    ranks = sps.rankdata(np.abs(d))
    positive = float(ranks[d > 0].sum())
    statistic = min(positive, n * (n + 1) / 2 - positive)
    _, ties = np.unique(np.abs(d), return_counts=True)
    if n <= EXACT_UP_TO and (ties == 1).all():
        p = min(1.0, 2.0 * float(_rank_sum_cdf(n)[int(statistic)]))
        return SignedRankResult(n, statistic, positive, p, "exact")
    variance = n * (n + 1) * (2 * n + 1) / 24 - float((ties**3 - ties).sum()) / 48
    if variance <= 0:
        return SignedRankResult(n, statistic, positive, np.nan, "not computed")
    gap = statistic - n * (n + 1) / 4
    z = (gap - 0.5 * np.sign(gap) * continuity) / np.sqrt(variance)
    method = "normal, continuity-corrected" if continuity else "normal"
    return SignedRankResult(n, statistic, positive, float(min(1.0, 2.0 * sps.norm.cdf(z))), method)
