"""Holm-Bonferroni adjustment of a family of p-values.

Holm (1979): sort the m p-values, multiply the i-th smallest (i from 0) by m - i, carry
the running maximum forward so adjusted p-values keep the order of the raw ones, and cap
at 1. Rejecting where the adjusted p-value is below alpha controls the family-wise error
rate at alpha, like Bonferroni, but rejects at least as often. The tests check it against
statsmodels' ``multipletests(method="holm")``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd


def holm_adjusted(pvalues) -> np.ndarray:
    """Holm-adjusted p-values, in the order given; NaN (a test not run) stays NaN."""
    p = np.asarray(pvalues, dtype=np.float64)
    adjusted = np.full(p.shape, np.nan)
    ran = np.flatnonzero(np.isfinite(p))
    order = ran[np.argsort(p[ran], kind="stable")]
    m = len(order)
    steps = (m - np.arange(m)) * p[order]
    adjusted[order] = np.minimum(1.0, np.maximum.accumulate(steps)) if m else steps
    return adjusted


def holm_by_cell(table: pd.DataFrame, groupby: Sequence[str], column: str = "p") -> pd.Series:
    """Holm-adjusted ``column`` within each cell of ``groupby`` (the whole table if empty)."""
    if not groupby:
        return pd.Series(holm_adjusted(table[column]), index=table.index)
    return table.groupby(list(groupby), sort=False)[column].transform(holm_adjusted)
