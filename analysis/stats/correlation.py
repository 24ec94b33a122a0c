"""How well objective metrics track subjective ratings, per system (as HVRNN reports)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats as sps


def subjective_objective_correlation(subjective: pd.Series, objective: pd.DataFrame
                                     ) -> tuple[pd.DataFrame, list[str]]:
    """Pearson r between per-system mean ratings and each objective metric column.

    ``subjective`` is indexed by system; ``objective`` has one row per system (index) and
    one numeric column per metric. Only systems present in both and with a finite
    metric value enter. Returns (table with columns metric, n_systems, r, p; notes on
    metrics that could not be correlated and why).
    """
    rows, notes = [], []
    for metric in objective.columns:
        both = pd.concat([subjective.rename("rating"), objective[metric]], axis=1, join="inner")
        both = both[np.isfinite(both.to_numpy(dtype=np.float64)).all(axis=1)]
        if len(both) < 3:
            notes.append(f"No correlation for {metric}: {len(both)} system(s) have both a mean "
                         "rating and the metric (three or more needed).")
            continue
        if both.std().eq(0).any():
            notes.append(f"No correlation for {metric}: constant across systems.")
            continue
        r, p = sps.pearsonr(both["rating"], both[metric])
        rows.append({"metric": metric, "n_systems": len(both), "r": float(r), "p": float(p)})
    return pd.DataFrame(rows, columns=["metric", "n_systems", "r", "p"]), notes
