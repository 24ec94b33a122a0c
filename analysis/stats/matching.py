"""Statistics of appropriateness pages: does a system's motion fit the control it was made for?

An appropriateness page (`analysis.designs`) shows one system's clip made for the shown
control (``matched``) and its clip made for another control, and asks which fits the
shown control better, on GENEA's five levels: the left clip clearly or slightly better,
no difference, the right clip slightly or clearly better. pingouin style: kept rows in
(two per page), tidy tables out, per system and cell of ``groupby`` (task x control
class by default).

- `appropriateness_pages`: one row per page, with its ``score``: +2 where the matched clip
  was clearly preferred, +1 slightly, 0 for no preference, -1 and -2 for the mismatched
  clip (a table without ``strength`` counts every preference as 1).
- `matched_preference`: per system, the share of pages preferring the matched clip with
  pages answered "no preference" split half and half (GENEA's convention), its Wilson
  interval, and an exact two-sided sign test of 50 % on the pages with a preference
  (a tie carries no sign), Holm-adjusted over the systems of a cell.
- `appropriateness_scores`: per system, the mean score on -2..+2 with a percentile
  bootstrap interval that resamples participants (a participant's pages move together,
  as they are not independent), seeded.
- `score_pairs`: every pair of systems compared by their participants' mean scores, a
  Wilcoxon signed-rank test over the participants who saw both, Holm-adjusted over the
  pairs of a cell.

Natural motion is the ceiling: a system that follows its control as well as NAT does
prefers its matched clip as often. 50 % and a score of 0 mean the motion does not show
which control it was made for.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np
import pandas as pd

from analysis.pages import NO_PREFERENCE, PAGE
from analysis.stats.minimums import few_participants_warning, too_few_for_bootstrap, with_participant_warnings
from analysis.stats.multiple_comparisons import holm_by_cell
from analysis.stats.preferences import sign_test_p, wilson_interval
from analysis.stats.signed_rank import signed_rank_test
from analysis.stats.anova import CELL, iter_cells

BOOTSTRAP_RESAMPLES = 2000


def appropriateness_pages(data: pd.DataFrame, groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """One row per page: *groupby, participant, page, system, matched_side, answer,
    strength, preferred (``matched``, ``mismatched`` or ``none``) and score (-2..+2)."""
    page = [*dict.fromkeys([*groupby, *PAGE])]
    matched = data[data["matched"]].set_index(page)
    strength = (matched["strength"].fillna(1) if "strength" in matched.columns
                else pd.Series(1, index=matched.index)).astype(np.int64)
    pages = pd.DataFrame({"system": matched["system"], "matched_side": matched["side"],
                          "answer": matched["answer"], "strength": strength}).sort_index().reset_index()
    decided = pages["answer"] != NO_PREFERENCE
    for_matched = pages["answer"] == pages["matched_side"]
    pages["preferred"] = np.where(decided, np.where(for_matched, "matched", "mismatched"), NO_PREFERENCE)
    pages["score"] = np.where(decided, np.where(for_matched, 1, -1) * pages["strength"], 0)
    pages.loc[~decided, "strength"] = 0
    return pages


def matched_preference(data: pd.DataFrame, groupby: Sequence[str] = CELL, alpha: float = 0.05,
                       confidence: float = 0.95) -> pd.DataFrame:
    """Per system: n_pages, matched, mismatched, no_preference (page counts),
    share_matched ((matched + no_preference / 2) / n_pages) with its Wilson interval
    (ci_low, ci_high), p (exact two-sided sign test of matched against mismatched),
    p_holm (over the systems of the cell), reject (p_holm < alpha), participants and
    warning (an interval from few participants, `analysis.stats.minimums`)."""
    pages = appropriateness_pages(data, groupby)
    for answer in ("matched", "mismatched", NO_PREFERENCE):
        pages[answer] = pages["preferred"] == answer
    table = (pages.groupby([*groupby, "system"], sort=True)
             .agg(n_pages=("score", "size"), matched=("matched", "sum"), mismatched=("mismatched", "sum"),
                  no_preference=(NO_PREFERENCE, "sum"))
             .reset_index())
    split = table["matched"] + table["no_preference"] / 2
    table["share_matched"] = split / table["n_pages"]
    table["ci_low"], table["ci_high"] = wilson_interval(split, table["n_pages"], confidence)
    table["p"] = sign_test_p(table["matched"], table["matched"] + table["mismatched"])
    table["p_holm"] = holm_by_cell(table, groupby)
    table["reject"] = table["p_holm"] < alpha
    return with_participant_warnings(table, pages, [*groupby, "system"])


def appropriateness_scores(data: pd.DataFrame, groupby: Sequence[str] = CELL, confidence: float = 0.95,
                           resamples: int = BOOTSTRAP_RESAMPLES, seed: int = 0) -> pd.DataFrame:
    """Per system: n_pages, n_participants, mean_score, ci_low and ci_high (percentile
    bootstrap over participants: each resample draws the system's participants with
    replacement and averages all their pages) and warning: why there is no interval (too
    few participants for a bootstrap, `analysis.stats.minimums`) or what makes it less certain
    than it looks (few participants), else empty."""
    rng = np.random.default_rng(seed)
    rows = []
    for key, frame in iter_cells(appropriateness_pages(data, groupby), groupby):
        for system, pages in frame.groupby("system", sort=True):
            per_participant = pages.groupby("participant")["score"].agg(["sum", "size"])
            sums, sizes = per_participant["sum"].to_numpy(float), per_participant["size"].to_numpy(float)
            warning = too_few_for_bootstrap(len(sums))
            low = high = np.nan
            if not warning:
                drawn = rng.integers(0, len(sums), (resamples, len(sums)))
                means = sums[drawn].sum(axis=1) / sizes[drawn].sum(axis=1)
                low, high = np.quantile(means, [(1 - confidence) / 2, (1 + confidence) / 2])
                warning = few_participants_warning(len(sums))
            rows.append({**key, "system": system, "n_pages": len(pages), "n_participants": len(sums),
                         "mean_score": float(pages["score"].mean()), "ci_low": float(low), "ci_high": float(high),
                         "warning": warning})
    return pd.DataFrame(rows, columns=[*groupby, "system", "n_pages", "n_participants", "mean_score",
                                       "ci_low", "ci_high", "warning"])


def score_pairs(data: pd.DataFrame, groupby: Sequence[str] = CELL, alpha: float = 0.05,
                continuity: bool = False) -> pd.DataFrame:
    """Per pair of systems (system_a < system_b): n_participants (who saw both),
    mean_diff (a - b, of their mean scores), statistic, method, p (two-sided Wilcoxon
    signed-rank test, `analysis.stats.signed_rank`, its normal approximation with ``continuity``
    correction or without), p_holm (over the pairs of the cell), reject and higher (the
    system with the larger rank sum, empty when equal)."""
    rows = []
    for key, frame in iter_cells(appropriateness_pages(data, groupby), groupby):
        means = frame.pivot_table(index="participant", columns="system", values="score", aggfunc="mean")
        for a, b in combinations(sorted(means.columns), 2):
            both = means[[a, b]].dropna()
            d = (both[a] - both[b]).to_numpy()
            test = signed_rank_test(d, continuity)
            negative = test.n_nonzero * (test.n_nonzero + 1) / 2 - test.positive_rank_sum
            rows.append({**key, "system_a": a, "system_b": b, "n_participants": len(d),
                         "mean_diff": float(d.mean()) if len(d) else np.nan, "statistic": test.statistic,
                         "method": test.method, "p": test.p,
                         "higher": "" if test.method == "not computed" else
                         a if test.positive_rank_sum > negative else b if negative > test.positive_rank_sum else ""})
    columns = [*groupby, "system_a", "system_b", "n_participants", "mean_diff", "statistic", "method", "p"]
    table = pd.DataFrame(rows, columns=[*columns, "higher"])
    table.insert(len(columns), "p_holm", holm_by_cell(table, groupby) if len(table) else [])
    table.insert(len(columns) + 1, "reject", table["p_holm"] < alpha)
    return table
