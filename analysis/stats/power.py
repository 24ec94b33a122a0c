"""How many more ratings give 80 % power to detect the difference observed so far.

For every pair of systems in a cell, the number of ratings (or pages) at which the
design's own pairwise test, at the study's alpha, would detect the difference observed
so far with the given power, and so how many more are needed and, at the present rate of
ratings per participant, how many more participants. The rate counts every participant
of the cell, not only those who saw the pair: with random pairing a new participant sees
a given pair only sometimes, and dividing by those who did would promise the pages from
too few participants (the tests check the figure by drawing that many participants). The observed difference is taken
as the true one, so these are planning numbers with the uncertainty of the estimate
itself; they say nothing about whether the difference is real.

Each pair is tested at alpha / m (Bonferroni), m the number of pairs compared in its cell:
every pair of systems for single and side-by-side pages, the pairs shown for pairwise.
That is the threshold Holm's procedure applies to the smallest p-value and lower than
the threshold it applies to every other one, so the numbers are, if anything, too high
for the Holm-corrected tests; for the single design's Tukey HSD they are close (Tukey's
critical value lies between the unadjusted and the Bonferroni one).

Closed forms, per design:

- single (independent ratings, Tukey HSD between systems): the two-sample z
  approximation with equal numbers per system,
  ``n = (z_{1-a/2} + z_power)^2 (s_a^2 + s_b^2) / d^2`` ratings per system, d the
  difference of means and s the standard deviations;
- side-by-side (Wilcoxon signed-rank test on per-page differences): Noether's (1987,
  JASA 82:645) formula ``n = (z_{1-a/2} + z_power)^2 / (3 (p' - 1/2)^2)`` pages with a
  non-zero difference, p' = P(D + D' > 0) for two independent page differences,
  estimated from the observed ones (ties with zero counted half); divided by the share
  of non-zero differences to count all pages;
- pairwise (exact sign test): the smallest number of pages with a preference from
  which the exact two-sided binomial test at alpha / m keeps at least the given power
  when the preference share is the observed one (power computed exactly from the
  binomial distribution; it saw-tooths with n, so the first n from which it no longer
  drops below the target); divided by the share of pages with a preference.

The tests check each against a simulation: drawing data with the observed effect at the
computed n and running the actual test gives the target power.

Looking at these numbers (or at p-values) while the study runs and stopping once a
difference is significant inflates the false-positive rate: with five looks at a
nominal 5 %, about 14 % (Armitage, McPherson & Rowe 1969). The study app fixes the
number of ratings per stimulus in advance (its target) and the report's tests assume
that fixed N; `SEQUENTIAL_LOOKS_NOTE` says so in the report.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
import pandas as pd
from scipy import stats as sps

from analysis.pages import NO_PREFERENCE
from analysis.stats.anova import CELL, iter_cells
from analysis.stats.preferences import preference_pages
from analysis.stats.within_page import page_differences

SEQUENTIAL_LOOKS_NOTE = (
    "Looking at the results repeatedly while ratings come in, and stopping once a "
    "difference is significant, inflates the false-positive rate (five looks at a nominal "
    "5 % give about 14 %, Armitage et al. 1969). The study fixes the number of ratings per "
    "stimulus in advance and these tests assume that fixed N; if ratings are added because "
    "of the power table, report it and treat the added comparisons as exploratory.")

_COLUMNS = ("system_a", "system_b", "effect", "alpha_pair", "unit", "n_now", "power_now",
            "n_needed", "n_more", "per_participant", "participants_more")


class PoweredDesign(Protocol):
    """What the power table asks of a table's design (`analysis.designs.base.RatingDesign`)."""

    def power_pairs(self, frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame: ...


def more_ratings_for_power(kept: pd.DataFrame, design: PoweredDesign, alpha: float = 0.05, power: float = 0.8,
                           groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """Per cell and pair of systems, the ratings (or pages) needed for ``power`` at ``alpha``.

    ``kept`` holds the kept ratings of the compared systems, in any design that compares
    systems (its ``design`` object says which of the closed forms below applies;
    `analysis.ratings.more_ratings` finds it from the table). Columns:
    *groupby, system_a, system_b, effect (single: mean_a - mean_b; side-by-side: p' - 1/2;
    pairwise: share preferring a - 1/2), alpha_pair (alpha / pairs in the cell), unit
    (``ratings per system`` or ``pages``), n_now, power_now (at n_now, same approximation),
    n_needed (NaN when the observed effect is zero or cannot be estimated), n_more (n_needed - n_now, at least
    0), per_participant (units of the pair per participant of the cell so far),
    participants_more.
    """
    rows = []
    for key, frame in iter_cells(kept, groupby):
        pairs = design.power_pairs(frame, alpha, power)
        if pairs.empty:
            continue
        rows.append(pairs.assign(**key))
    table = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=[*groupby, *_COLUMNS])
    table["n_more"] = np.maximum(table["n_needed"] - table["n_now"], 0)
    table["participants_more"] = np.ceil(table["n_more"] / table["per_participant"])
    return table[[*groupby, *_COLUMNS]].reset_index(drop=True)


def _z(alpha_pair: float, power: float) -> float:
    return float(sps.norm.ppf(1 - alpha_pair / 2) + sps.norm.ppf(power))


def single_pairs(frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
    """One cell's pairs of systems rated on separate pages (two-sample z approximation)."""
    stats = frame.groupby("system", sort=True)["value"].agg(["size", "mean", "var"])
    stats = stats[stats["size"] >= 2]
    k = len(stats)
    alpha_pair = alpha / max(1, k * (k - 1) // 2)
    a, b = np.triu_indices(k, 1)
    n, mean, var = (stats[c].to_numpy(np.float64) for c in ("size", "mean", "var"))
    d = mean[a] - mean[b]
    n_now = np.minimum(n[a], n[b])
    with np.errstate(divide="ignore", invalid="ignore"):
        needed = np.where(d != 0, np.ceil(_z(alpha_pair, power) ** 2 * (var[a] + var[b]) / d**2), np.nan)
        standardised = np.abs(d) / np.sqrt(var[a] / n[a] + var[b] / n[b])
    table = pd.DataFrame({"system_a": stats.index[a], "system_b": stats.index[b], "effect": d,
                          "n_now": n_now.astype(np.int64), "n_needed": needed,
                          "power_now": _normal_power(np.nan_to_num(standardised, nan=np.inf), alpha_pair),
                          "per_participant": n_now / frame["participant"].nunique()})
    return table.assign(alpha_pair=alpha_pair, unit="ratings per system")


def _normal_power(standardised, alpha_pair: float):
    return sps.norm.cdf(standardised - sps.norm.ppf(1 - alpha_pair / 2))


def walsh_positive_share(differences) -> float:
    """p' = P(D + D' > 0) over pairs i < j of the differences, a tie counted half."""
    d = np.sort(np.asarray(differences, dtype=np.float64))
    n = len(d)
    if n < 2:
        return np.nan
    # pairs (i, j), i != j, with d_i + d_j > 0 (and = 0), counted by binary search
    above = n - np.searchsorted(d, -d, side="right")
    equal = np.searchsorted(d, -d, side="right") - np.searchsorted(d, -d, side="left")
    self_above, self_equal = int((d > 0).sum()), int((d == 0).sum())
    pairs_above = (above.sum() - self_above) / 2
    pairs_equal = (equal.sum() - self_equal) / 2
    return float((pairs_above + pairs_equal / 2) / (n * (n - 1) / 2))


def side_by_side_pairs(frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
    """One cell's pairs of systems rated on the same pages (Noether's formula)."""
    diffs = page_differences(frame, groupby=())
    participants = frame["participant"].nunique()
    alpha_pair = alpha / max(1, diffs.groupby(["system_a", "system_b"]).ngroups)
    rows = []
    for (a, b), pair in diffs.groupby(["system_a", "system_b"], sort=True):
        d = pair["difference"].to_numpy()
        nonzero = d[d != 0]
        share_nonzero = len(nonzero) / len(d)
        effect = walsh_positive_share(nonzero) - 0.5
        needed = (np.ceil(_z(alpha_pair, power) ** 2 / (3 * effect**2) / share_nonzero)
                  if effect and np.isfinite(effect) else np.nan)
        rows.append({"system_a": a, "system_b": b, "effect": effect, "n_now": len(d),
                     "n_needed": needed,
                     "power_now": _normal_power(np.sqrt(3 * len(nonzero)) * abs(effect), alpha_pair)
                     if np.isfinite(effect) else np.nan,
                     "per_participant": len(d) / participants})
    return _finish(rows, alpha_pair, "pages")


def sign_test_power(n: np.ndarray, share: float, alpha: float) -> np.ndarray:
    """Exact power of the two-sided binomial test of 1/2 at ``alpha`` with n trials."""
    n = np.asarray(n)
    # the largest c with 2 P(X <= c | 1/2) <= alpha; the test rejects at k <= c or k >= n - c
    c = sps.binom.ppf(alpha / 2, n, 0.5)
    c = np.where(sps.binom.cdf(c, n, 0.5) > alpha / 2, c - 1, c)
    return sps.binom.cdf(c, n, share) + sps.binom.sf(n - c - 1, n, share)


def sign_test_trials_for_power(share: float, alpha: float, power: float) -> float:
    """The smallest n from which the exact sign test keeps at least ``power`` (NaN at 1/2)."""
    if not np.isfinite(share) or share == 0.5:
        return np.nan
    if share in (0.0, 1.0):
        # every trial goes one way: the test rejects once 2 * 2^-n <= alpha
        return float(np.ceil(np.log2(2 / alpha)))
    guess = _z(alpha, power) ** 2 * 0.25 / (share - 0.5) ** 2
    n = np.arange(1, int(4 * guess) + 200)
    short = np.flatnonzero(sign_test_power(n, share, alpha) < power)
    return float(n[short[-1] + 1]) if len(short) else 1.0


def pairwise_pairs(frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
    """One cell's pairs of systems compared by preference (exact sign test)."""
    pages = preference_pages(frame, groupby=())
    participants = frame["participant"].nunique()
    alpha_pair = alpha / max(1, pages.groupby(["system_a", "system_b"]).ngroups)
    rows = []
    for (a, b), pair in pages.groupby(["system_a", "system_b"], sort=True):
        decided = pair[pair["answer"] != NO_PREFERENCE]
        share = (decided["winner"] == a).mean() if len(decided) else np.nan
        trials = sign_test_trials_for_power(share, alpha_pair, power)
        share_decided = len(decided) / len(pair)
        rows.append({"system_a": a, "system_b": b, "effect": share - 0.5, "n_now": len(pair),
                     "n_needed": np.ceil(trials / share_decided) if share_decided else np.nan,
                     "power_now": float(sign_test_power(len(decided), share, alpha_pair))
                     if len(decided) else np.nan,
                     "per_participant": len(pair) / participants})
    return _finish(rows, alpha_pair, "pages")


def _finish(rows: list[dict], alpha_pair: float, unit: str) -> pd.DataFrame:
    table = pd.DataFrame(rows, columns=["system_a", "system_b", "effect", "n_now", "n_needed",
                                        "power_now", "per_participant"])
    return table.assign(alpha_pair=alpha_pair, unit=unit)


# Planning before any rating exists: the same tests' closed forms, from an expected effect
# instead of an observed one (the study app's plan, locked when a study opens).


def pairs_of(systems: int) -> int:
    """The pairs among ``systems`` compared systems, which share alpha (Bonferroni)."""
    return max(1, systems * (systems - 1) // 2)


def ratings_per_system_for_effect(d: float, pairs: int, alpha: float = 0.05, power: float = 0.8) -> int:
    """Ratings per system at which the two-sample z approximation detects a standardised
    difference of means ``d`` (Cohen's d, equal variances) at alpha / pairs with ``power``:
    ``n = 2 (z_{1-a/2} + z_power)^2 / d^2``, as `single_pairs` with s_a = s_b = 1."""
    _check_effect(d, 0, np.inf, "a standardised difference")
    return int(np.ceil(2 * _z(alpha / pairs, power) ** 2 / d**2))


def pages_for_page_effect(d: float, pairs: int, alpha: float = 0.05, power: float = 0.8) -> int:
    """Pages at which the Wilcoxon signed-rank test detects a mean per-page difference of
    ``d`` standard deviations of the differences (normal differences), by Noether's formula
    as `side_by_side_pairs` applies it: p' = P(D + D' > 0) = Phi(sqrt(2) d)."""
    _check_effect(d, 0, np.inf, "a standardised difference")
    effect = float(sps.norm.cdf(np.sqrt(2) * d)) - 0.5
    return int(np.ceil(_z(alpha / pairs, power) ** 2 / (3 * effect**2)))


def pages_for_preference(share: float, pairs: int, alpha: float = 0.05, power: float = 0.8) -> int:
    """Pages with a preference at which the exact sign test detects ``share`` of them
    preferring the better system (`sign_test_trials_for_power`, at alpha / pairs)."""
    _check_effect(share, 0.5, 1, "a share of pages")
    return int(sign_test_trials_for_power(share, alpha / pairs, power))


def _check_effect(effect: float, low: float, high: float, what: str) -> None:
    """A ValueError unless ``low < effect <= high`` (no test detects no effect)."""
    if not (np.isfinite(effect) and low < effect <= high):
        limit = f" and at most {high:g}" if np.isfinite(high) else ""
        raise ValueError(f"the expected effect, {what}, must lie above {low:g}{limit}; got {effect:g}")


def power_summary(table: pd.DataFrame, alpha: float = 0.05, power: float = 0.8) -> str:
    """`more_ratings_for_power` output in words, with `SEQUENTIAL_LOOKS_NOTE`."""
    if table.empty:
        return ""
    short = table[table["n_more"] > 0].sort_values("n_more")
    where = [c for c in CELL if c in table.columns]
    unreachable = int(table["n_needed"].isna().sum())
    if short.empty and not unreachable:
        found = f"every pair already has {power * 100:g} % power to detect the difference observed so far."
    else:
        parts = [f"{r.system_a}-{r.system_b}"
                 + (f" ({' · '.join(str(getattr(r, c)) for c in where)})" if where else "")
                 + f": {int(r.n_more)} more {r.unit}, about {int(r.participants_more)} participants"
                 for r in short.itertuples(index=False)]
        found = (f"for {power * 100:g} % power to detect the difference observed so far, "
                 + ("; ".join(parts) if parts else "no pair needs more")
                 + (f"; {unreachable} pair(s) show no difference, or too few answers to "
                    "estimate one, so no number can be given." if unreachable else "."))
    return (f"**Power.** At α = {alpha:g}, split over each cell's pairs (Bonferroni), "
            f"{found} " + SEQUENTIAL_LOOKS_NOTE)
