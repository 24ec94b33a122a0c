"""Significance tests on ratings: one-way ANOVA, Tukey HSD, means with confidence intervals.

pingouin style: each function takes a tidy DataFrame (one row per kept rating) and
returns a tidy DataFrame, computed separately for every cell of the ``groupby`` columns
(by default each task x control class, the columns of MoGlow Table 2).

Preconditions, checked with a clear AnalysisInputError: every system in a cell has at
least two ratings, and ANOVA / Tukey need at least two systems and some within-system
variation. `too_few_ratings` and `comparable_cells` find what breaks them, so the report
can leave it out and say so in its notes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats as sps

from analysis.errors import AnalysisInputError
from analysis.stats.studentized_range import studentized_range_ppf, studentized_range_sf

CELL = ("task", "control_class")


def iter_cells(data: pd.DataFrame, groupby: Sequence[str]):
    """(key dict, frame) per cell; one cell holding everything when groupby is empty."""
    if not groupby:
        yield {}, data
        return
    for key, frame in data.groupby(list(groupby), sort=True):
        yield dict(zip(groupby, key)), frame


def _group_stats(frame: pd.DataFrame, dv: str, between: str) -> pd.DataFrame:
    grouped = frame.groupby(between, sort=True)[dv]
    table = pd.DataFrame({"n": grouped.size(), "mean": grouped.mean(), "var": grouped.var(ddof=1)})
    few = table.index[table["n"] < 2].tolist()
    if few:
        raise AnalysisInputError(
            f"system(s) {', '.join(map(str, few))} have fewer than two ratings; their "
            "variance and confidence interval are undefined"
        )
    return table


def too_few_ratings(data: pd.DataFrame, between: str = "system",
                    groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """Systems with fewer than two ratings in a cell: columns *groupby, system, n."""
    counts = data.groupby([*groupby, between]).size().rename("n").reset_index()
    return counts[counts["n"] < 2].reset_index(drop=True)


def comparable_cells(data: pd.DataFrame, dv: str = "value", between: str = "system",
                     groupby: Sequence[str] = CELL) -> tuple[pd.DataFrame, list[str]]:
    """Keep only cells where systems can be compared (two or more systems, some spread)."""
    notes, keep = [], []
    for key, frame in iter_cells(data, groupby):
        where = ", ".join(f"{c}={v}" for c, v in key.items()) or "all ratings"
        if frame[between].nunique() < 2:
            notes.append(f"No ANOVA or Tukey HSD for {where}: fewer than two systems rated.")
        elif (frame.groupby(between)[dv].var(ddof=1) == 0).all():
            notes.append(f"No ANOVA or Tukey HSD for {where}: no rating variation within any system.")
        else:
            keep.append(frame)
    return (pd.concat(keep) if keep else data.iloc[:0]), notes


def system_means(data: pd.DataFrame, dv: str = "value", between: str = "system",
                 groupby: Sequence[str] = CELL, confidence: float = 0.95) -> pd.DataFrame:
    """Mean and t-based confidence interval per system and cell.

    Columns: *groupby, system, n, mean, sd, sem, ci_half, ci_low, ci_high, where ci_half
    is t_{(1+confidence)/2, n-1} * sd / sqrt(n), the ``±`` of MoGlow Table 2.
    """
    rows = []
    for key, frame in iter_cells(data, groupby):
        table = _group_stats(frame, dv, between)
        sd = np.sqrt(table["var"])
        sem = sd / np.sqrt(table["n"])
        half = sps.t.ppf(0.5 + confidence / 2, table["n"] - 1) * sem
        rows.append(pd.DataFrame({**key, between: table.index, "n": table["n"].to_numpy(),
                                  "mean": table["mean"].to_numpy(), "sd": sd.to_numpy(),
                                  "sem": sem.to_numpy(), "ci_half": half.to_numpy(),
                                  "ci_low": (table["mean"] - half).to_numpy(),
                                  "ci_high": (table["mean"] + half).to_numpy()}))
    return pd.concat(rows, ignore_index=True)


def anova(data: pd.DataFrame, dv: str = "value", between: str = "system",
          groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """One-way between-systems ANOVA per cell.

    Columns: *groupby, n_systems, n_ratings, df_between, df_within, F, p, eta_squared.
    """
    rows = []
    for key, frame in iter_cells(data, groupby):
        table = _group_stats(frame, dv, between)
        k, n = len(table), int(table["n"].sum())
        if k < 2:
            raise AnalysisInputError(f"ANOVA needs two or more systems; cell {key} has {k}")
        grand = (table["n"] * table["mean"]).sum() / n
        ss_between = float((table["n"] * (table["mean"] - grand) ** 2).sum())
        ss_within = float(((table["n"] - 1) * table["var"]).sum())
        if ss_within == 0:
            raise AnalysisInputError(f"ANOVA undefined in cell {key}: no variation within systems")
        f = (ss_between / (k - 1)) / (ss_within / (n - k))
        rows.append({**key, "n_systems": k, "n_ratings": n, "df_between": k - 1,
                     "df_within": n - k, "F": f, "p": float(sps.f.sf(f, k - 1, n - k)),
                     "eta_squared": ss_between / (ss_between + ss_within)})
    return pd.DataFrame(rows)


def tukey_hsd(data: pd.DataFrame, dv: str = "value", between: str = "system",
              groupby: Sequence[str] = CELL, alpha: float = 0.05) -> pd.DataFrame:
    """Tukey's honestly significant difference over all pairs of systems, per cell.

    Tukey-Kramer form (unequal group sizes). Columns: *groupby, system_a, system_b,
    mean_a, mean_b, diff (mean_b - mean_a, as statsmodels reports it), se, q, p_adj,
    ci_low, ci_high (simultaneous 1 - alpha intervals for diff), reject (p_adj < alpha).
    """
    rows = []
    for key, frame in iter_cells(data, groupby):
        table = _group_stats(frame, dv, between)
        k, n = len(table), int(table["n"].sum())
        if k < 2:
            raise AnalysisInputError(f"Tukey HSD needs two or more systems; cell {key} has {k}")
        mse = float(((table["n"] - 1) * table["var"]).sum()) / (n - k)
        if mse == 0:
            raise AnalysisInputError(f"Tukey HSD undefined in cell {key}: no variation within systems")
        a, b = np.triu_indices(k, 1)
        means, counts = table["mean"].to_numpy(), table["n"].to_numpy()
        diff = means[b] - means[a]
        se = np.sqrt(mse / 2 * (1 / counts[a] + 1 / counts[b]))
        q = np.abs(diff) / se
        p = studentized_range_sf(q, k, n - k)
        margin = studentized_range_ppf(1 - alpha, k, n - k) * se
        rows.append(pd.DataFrame({**key, "system_a": table.index[a], "system_b": table.index[b],
                                  "mean_a": means[a], "mean_b": means[b], "diff": diff,
                                  "se": se, "q": q, "p_adj": p, "ci_low": diff - margin,
                                  "ci_high": diff + margin, "reject": p < alpha}))
    return pd.concat(rows, ignore_index=True)


def pvalue_matrix(pairs: pd.DataFrame) -> pd.DataFrame:
    """Square matrix of adjusted p-values from one cell of `tukey_hsd` output.

    The diagonal (a system against itself) is NaN by construction; writers render it
    as a dash.
    """
    systems = sorted(set(pairs["system_a"].unique()) | set(pairs["system_b"].unique()))
    where = {s: i for i, s in enumerate(systems)}
    a = pairs["system_a"].map(where).to_numpy()
    b = pairs["system_b"].map(where).to_numpy()
    values = np.full((len(systems), len(systems)), np.nan)
    values[a, b] = values[b, a] = pairs["p_adj"].to_numpy()
    matrix = pd.DataFrame(values, index=pd.Index(systems, name="system"), columns=systems)
    return matrix
