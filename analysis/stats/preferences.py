"""Statistics of pairwise preference ratings: shares, sign tests, side bias.

A pairwise page shows two systems' clips for the same control and asks which is better;
its answer is ``left``, ``right`` or ``none`` (no preference). pingouin style: tidy kept
rows in (two per page, see `analysis.designs`), tidy tables out, per cell of ``groupby``
(task x control class by default).

How "no preference" is handled: as the sign test treats a zero difference. A page
answered ``none`` says nothing about which system is better, so it is left out of the
preference share, the binomial test and the Bradley-Terry scale; its count and share
are reported beside them (``no_preference``, ``no_preference_share``), so a reader sees
how many pages the tests rest on.

- `preference_pages`: one row per page (system_left, system_right, answer, winner).
- `preference_pairs`: per pair of systems, wins, the share preferring system_a among
  pages with a preference and its Wilson interval, an exact two-sided binomial (sign)
  test of share = 1/2, Holm-Bonferroni adjusted over all pairs of the cell.
- `side_bias`: the share of stated preferences that went to the left clip, tested the
  same way; sides are balanced by the study, so a bias shows a habit of the raters.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats as sps

from analysis.pages import NO_PREFERENCE, PAGE, SIDES
from analysis.stats.minimums import with_participant_warnings
from analysis.stats.multiple_comparisons import holm_by_cell
from analysis.stats.anova import CELL, iter_cells


def wilson_interval(successes, trials, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for a binomial proportion (NaN where there are no trials)."""
    x, n = np.asarray(successes, dtype=np.float64), np.asarray(trials, dtype=np.float64)
    z = sps.norm.ppf(0.5 + confidence / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (x + z**2 / 2) / (n + z**2)
        half = z / (n + z**2) * np.sqrt(x * (n - x) / n + z**2 / 4)
    return np.where(n > 0, centre - half, np.nan), np.where(n > 0, centre + half, np.nan)


def sign_test_p(successes, trials) -> np.ndarray:
    """Exact two-sided binomial test of a proportion of 1/2: min(1, 2 P(X <= min(k, n-k)))."""
    k, n = np.asarray(successes), np.asarray(trials)
    p = np.minimum(1.0, 2.0 * sps.binom.cdf(np.minimum(k, n - k), n, 0.5))
    return np.where(n > 0, p, np.nan)


def preference_pages(data: pd.DataFrame, groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """One row per page: *groupby, participant, page, system_left, system_right, answer,
    winner and loser (empty for no preference), system_a / system_b (the pair, sorted).

    A page of which only one row is given (the caller left out its other clip, an
    attention check's, say) compares nothing and is left out.
    """
    page = [*dict.fromkeys([*groupby, *PAGE])]
    left, right = (data[data["side"] == side].set_index(page) for side in SIDES)
    pages = pd.concat({"system_left": left["system"], "system_right": right["system"],
                       "answer": left["answer"]}, axis=1, join="inner").sort_index().reset_index()
    decided = pages["answer"] != NO_PREFERENCE
    left_won = pages["answer"] == "left"
    pages["winner"] = np.where(decided, np.where(left_won, pages["system_left"], pages["system_right"]), "")
    pages["loser"] = np.where(decided, np.where(left_won, pages["system_right"], pages["system_left"]), "")
    left_first = (pages["system_left"] <= pages["system_right"]).to_numpy()
    pages["system_a"] = np.where(left_first, pages["system_left"], pages["system_right"])
    pages["system_b"] = np.where(left_first, pages["system_right"], pages["system_left"])
    return pages


def preference_pairs(data: pd.DataFrame, groupby: Sequence[str] = CELL, alpha: float = 0.05,
                     confidence: float = 0.95) -> pd.DataFrame:
    """Preference share and sign test per pair of systems shown together.

    Columns: *groupby, system_a, system_b, n_pages, wins_a, wins_b, no_preference,
    no_preference_share, share_a (wins_a / (wins_a + wins_b)), share_ci_low,
    share_ci_high (Wilson), p (exact two-sided binomial test of share_a = 1/2), p_holm
    (over all pairs of the cell), reject (p_holm < alpha), preferred (the system
    preferred more often, empty when equal), participants (who saw the pair) and warning
    (an interval from few participants, `analysis.stats.minimums`).
    """
    pages = preference_pages(data, groupby)
    pages["a_won"] = pages["winner"] == pages["system_a"]
    pages["b_won"] = pages["winner"] == pages["system_b"]
    pages["tie"] = pages["answer"] == NO_PREFERENCE
    table = (pages.groupby([*groupby, "system_a", "system_b"], sort=True)
             .agg(n_pages=("answer", "size"), wins_a=("a_won", "sum"), wins_b=("b_won", "sum"),
                  no_preference=("tie", "sum"))
             .reset_index())
    decided = table["wins_a"] + table["wins_b"]
    table["no_preference_share"] = table["no_preference"] / table["n_pages"]
    with np.errstate(invalid="ignore", divide="ignore"):
        table["share_a"] = np.where(decided > 0, table["wins_a"] / decided, np.nan)
    table["share_ci_low"], table["share_ci_high"] = wilson_interval(table["wins_a"], decided, confidence)
    table["p"] = sign_test_p(table["wins_a"], decided)
    table["p_holm"] = holm_by_cell(table, groupby)
    table["reject"] = table["p_holm"] < alpha
    table["preferred"] = np.where(table["wins_a"] > table["wins_b"], table["system_a"],
                                  np.where(table["wins_b"] > table["wins_a"], table["system_b"], ""))
    return with_participant_warnings(table, pages, [*groupby, "system_a", "system_b"])


def side_bias(data: pd.DataFrame, groupby: Sequence[str] = CELL,
              confidence: float = 0.95) -> pd.DataFrame:
    """Per cell: n_decided (pages with a preference), left (of them answered left),
    left_share with its Wilson interval, and p (exact two-sided binomial test of 1/2)."""
    rows = []
    for key, frame in iter_cells(preference_pages(data, groupby), groupby):
        decided = int((frame["answer"] != NO_PREFERENCE).sum())
        left = int((frame["answer"] == "left").sum())
        low, high = wilson_interval(left, decided, confidence)
        rows.append({**key, "n_decided": decided, "left": left,
                     "left_share": left / decided if decided else np.nan,
                     "ci_low": float(low), "ci_high": float(high),
                     "p": float(sign_test_p(left, decided))})
    return pd.DataFrame(rows)
