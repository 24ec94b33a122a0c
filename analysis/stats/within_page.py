"""Statistics of side-by-side ratings (HEMVIP / MUSHRA pages), as GENEA analyses them.

On a side-by-side page one participant rates several systems' clips for the same
control, so two systems are compared on the pages that show both: the per-page
difference of their ratings. pingouin style: tidy kept ratings in (one row per clip
rated, with ``page``), tidy tables out, computed separately per cell of ``groupby``
(task x control class by default).

- `median_and_mean`: per system the median with its distribution-free 95 % interval
  (order statistics: the k-th smallest and k-th largest rating, k the largest rank with
  2 P(Bin(n, 1/2) < k) <= 1 - confidence, checked against scipy.stats.quantile_test) and
  the mean with its t interval (`analysis.stats.anova.system_means`).
- `page_differences`: the per-page differences of every pair of systems.
- `signed_rank_pairs`: a two-sided Wilcoxon signed-rank test per pair on those
  differences (`analysis.stats.signed_rank`), Holm-Bonferroni adjusted over all pairs of the
  cell.
- `significance_matrix`: +1 / -1 / 0 per (row system, column system): rated
  significantly higher, lower, or not significantly different.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np
import pandas as pd
from scipy import stats as sps

from analysis.pages import PAGE
from analysis.stats.minimums import with_participant_warnings
from analysis.stats.multiple_comparisons import holm_by_cell
from analysis.stats.signed_rank import signed_rank_test
from analysis.stats.anova import CELL, iter_cells, system_means


def median_interval(values, confidence: float = 0.95) -> tuple[float, float]:
    """Distribution-free interval for the median from order statistics (NaN when n < 6)."""
    x = np.sort(np.asarray(values, dtype=np.float64))
    n = len(x)
    k = int(sps.binom.ppf((1 - confidence) / 2, n, 0.5)) if n else 0
    if k < 1:
        return np.nan, np.nan
    return float(x[k - 1]), float(x[n - k])


def median_and_mean(data: pd.DataFrame, dv: str = "value", between: str = "system",
                    groupby: Sequence[str] = CELL, confidence: float = 0.95) -> pd.DataFrame:
    """Per system and cell: n, median, median_ci_low, median_ci_high, mean, ci_half,
    ci_low, ci_high (every system needs two or more ratings, as for `system_means`),
    participants and warning (intervals from few participants, `analysis.stats.minimums`)."""
    means = system_means(data, dv, between, groupby, confidence)
    medians = []
    for key, frame in iter_cells(data, groupby):
        for system, values in frame.groupby(between, sort=True)[dv]:
            low, high = median_interval(values, confidence)
            medians.append({**key, between: system, "median": float(values.median()),
                            "median_ci_low": low, "median_ci_high": high})
    table = means.merge(pd.DataFrame(medians), on=[*groupby, between])
    table = table[[*groupby, between, "n", "median", "median_ci_low", "median_ci_high",
                   "mean", "sd", "ci_half", "ci_low", "ci_high"]]
    return with_participant_warnings(table, data, [*groupby, between])


def page_differences(data: pd.DataFrame, dv: str = "value", between: str = "system",
                     groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """Per cell, pair (system_a < system_b) and page showing both: value_a, value_b, difference."""
    rows = []
    page = [c for c in PAGE if c not in groupby]
    for key, frame in iter_cells(data, groupby):
        wide = frame.pivot_table(index=page, columns=between, values=dv, aggfunc="first")
        for a, b in combinations(sorted(wide.columns), 2):
            both = wide[[a, b]].dropna()
            rows.append(pd.DataFrame({**key, "system_a": a, "system_b": b,
                                      **{c: both.index.get_level_values(c) for c in page},
                                      "value_a": both[a].to_numpy(), "value_b": both[b].to_numpy(),
                                      "difference": (both[a] - both[b]).to_numpy()}))
    columns = [*groupby, "system_a", "system_b", *page, "value_a", "value_b", "difference"]
    return pd.concat(rows, ignore_index=True)[columns] if rows else pd.DataFrame(columns=columns)


def signed_rank_pairs(data: pd.DataFrame, dv: str = "value", between: str = "system",
                      groupby: Sequence[str] = CELL, alpha: float = 0.05,
                      continuity: bool = False) -> pd.DataFrame:
    """Wilcoxon signed-rank test per pair of systems on their per-page differences.

    Columns: *groupby, system_a, system_b, n_pages (pages showing both), n_nonzero
    (pages rating them differently: the test's n), median_diff and mean_diff (a - b),
    statistic (min of the positive and negative rank sums), method (exact, normal, or
    normal with ``continuity`` correction),
    p, p_holm (over all pairs of the cell), reject (p_holm < alpha), higher (the system
    with the larger rank sum, empty when equal or not computed).
    """
    diffs = page_differences(data, dv, between, groupby)
    rows = []
    for (*key, a, b), frame in diffs.groupby([*groupby, "system_a", "system_b"], sort=True):
        d = frame["difference"].to_numpy()
        test = signed_rank_test(d, continuity)
        positive = test.positive_rank_sum
        negative = test.n_nonzero * (test.n_nonzero + 1) / 2 - positive
        rows.append({**dict(zip(groupby, key)), "system_a": a, "system_b": b,
                     "n_pages": len(d), "n_nonzero": test.n_nonzero,
                     "median_diff": float(np.median(d)), "mean_diff": float(d.mean()),
                     "statistic": test.statistic, "method": test.method, "p": test.p,
                     "higher": a if positive > negative else b if negative > positive else ""})
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    table.insert(table.columns.get_loc("higher"), "p_holm", holm_by_cell(table, groupby))
    table.insert(table.columns.get_loc("higher"), "reject", table["p_holm"] < alpha)
    table.loc[table["method"] == "not computed", "higher"] = ""
    return table


def significance_matrix(pairs: pd.DataFrame, order: Sequence[str]) -> pd.DataFrame:
    """One cell of `signed_rank_pairs` as a square frame: +1 where the row system was rated
    significantly higher than the column system, -1 lower, 0 no significant difference,
    NaN on the diagonal and where no test could be run."""
    matrix = pd.DataFrame(np.nan, index=pd.Index(order, name="system"), columns=list(order))
    for row in pairs.itertuples(index=False):
        if row.system_a not in matrix.index or row.system_b not in matrix.index or np.isnan(row.p):
            continue
        sign = 0.0 if not row.reject else 1.0 if row.higher == row.system_a else -1.0
        matrix.loc[row.system_a, row.system_b] = sign
        matrix.loc[row.system_b, row.system_a] = -sign
    return matrix
