"""A Bradley-Terry scale from pairwise preferences, with Wald confidence intervals.

The model: system i is preferred over system j with probability
``exp(b_i) / (exp(b_i) + exp(b_j))``. The strengths ``b`` are on a log-odds scale,
centred to sum to zero, so a difference of 1 between two systems means odds of e = 2.7
to 1 that a rater prefers the higher one. Pages with no preference are left out, as in
the sign tests (`analysis.stats.preferences`).

Fitting: Hunter's (2004) MM iterations, ``g_i <- W_i / sum_j n_ij / (g_i + g_j)`` with
W_i the wins of i and n_ij the decided pages of the pair, which increase the likelihood
at every step. The maximum exists only when the "beat" graph is strongly connected (for
every split of the systems into two groups, some system of each group beat one of the
other); otherwise a system that never lost (or never won) has an infinite strength, and
the cell is left out with a note.

Intervals: the inverse Fisher information ``sum_ij n_ij p_ij (1 - p_ij) (e_i - e_j)(e_i -
e_j)'`` is singular along the all-ones direction; its Moore-Penrose inverse is the
covariance of the sum-to-zero strengths. Software that fixes one system at zero instead
(a logistic regression without that system's column, R's BradleyTerry2) reports each
strength against it: ``b_i - b_ref`` with variance ``C_ii + C_rr - 2 C_ir``, given beside
the centred ones (``strength_vs_reference``, ``se_vs_reference``), and the covariance
itself is written out (`bradley_terry_covariance`) for any other contrast. The tests
check estimates and standard errors of both forms against a logistic regression
(statsmodels GLM) of the same comparisons.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats as sps
from scipy.sparse.csgraph import connected_components

from analysis.errors import AnalysisInputError
from analysis.stats.minimums import with_participant_warnings
from analysis.stats.anova import CELL, iter_cells

_TOLERANCE = 1e-10
_MAX_ITERATIONS = 100_000


def win_matrix(pages: pd.DataFrame) -> tuple[list[str], np.ndarray]:
    """Systems (sorted) and wins[i, j] = pages on which system i was preferred over j."""
    systems = sorted(set(pages["system_left"]) | set(pages["system_right"]))
    where = {s: i for i, s in enumerate(systems)}
    decided = pages[pages["winner"] != ""]
    wins = np.zeros((len(systems), len(systems)))
    np.add.at(wins, (decided["winner"].map(where).to_numpy(dtype=int),
                     decided["loser"].map(where).to_numpy(dtype=int)), 1.0)
    return systems, wins


def fit_bradley_terry(wins: np.ndarray, systems: Sequence[str] | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Centred log-strengths, their covariance, and the MM iterations used.

    Raises AnalysisInputError when the maximum-likelihood strengths do not exist, naming
    why (and the ``systems``, where given, of groups never compared).
    """
    k = len(wins)
    count, _ = connected_components(wins > 0, directed=True, connection="strong")
    if k < 2 or count > 1:
        raise AnalysisInputError(_not_connected_reason(wins, systems or [str(i) for i in range(k)]))
    games = wins + wins.T
    won = wins.sum(axis=1)
    strength = np.ones(k)
    for iteration in range(1, _MAX_ITERATIONS + 1):
        denominator = (games / (strength[:, None] + strength[None, :])).sum(axis=1)
        updated = won / denominator
        updated /= np.exp(np.log(updated).mean())
        change = np.abs(np.log(updated) - np.log(strength)).max()
        strength = updated
        if change < _TOLERANCE:
            break
    else:
        raise AnalysisInputError(f"Bradley-Terry MM did not converge in {_MAX_ITERATIONS} iterations")
    b = np.log(strength)
    p = 1.0 / (1.0 + np.exp(b[None, :] - b[:, None]))  # p[i, j]: i preferred over j
    weight = games * p * p.T
    information = np.diag(weight.sum(axis=1)) - weight
    return b, np.linalg.pinv(information), iteration


def never_compared_reason(compared: np.ndarray, systems: Sequence[str]) -> str:
    """Why no scale joins systems that fall into groups never compared with each other
    (``compared[i, j]``: some page put i and j side by side), or "" when every system is
    compared, directly or through others, with every other. A separated graph, where
    the groups were compared but one always won, is another cause (with another cure)."""
    count, label = connected_components(compared | compared.T, directed=False)
    if count < 2:
        return ""
    groups = "; ".join("{" + ", ".join(systems[i] for i in np.flatnonzero(label == g)) + "}" for g in range(count))
    return (f"the systems fall into {count} groups never compared with each other ({groups}): no page puts the "
            "groups on one scale; compare a system of each group with one of another")


def _not_connected_reason(wins: np.ndarray, systems: Sequence[str]) -> str:
    if len(wins) < 2:
        return "fewer than two systems were compared"
    if not wins.any():
        return "no page stated a preference"
    apart = never_compared_reason(wins > 0, systems)
    if apart:
        return apart
    never_lost = np.flatnonzero((wins.sum(axis=0) == 0))
    never_won = np.flatnonzero((wins.sum(axis=1) == 0))
    if len(never_lost) or len(never_won):
        return (f"{len(never_lost)} system(s) never lost and {len(never_won)} never won a "
                "comparison, so their strengths are unbounded")
    return ("the systems fall into groups of which one always beat the other (they were compared, but the "
            "other group never won), so the groups' distance is unbounded")


def _cell_fits(pages: pd.DataFrame, groupby: Sequence[str], notes: list[str]):
    """(key, systems, wins, centred strengths, covariance) per cell with a fit; the
    cells without one are named in ``notes``."""
    for key, frame in iter_cells(pages, groupby):
        systems, wins = win_matrix(frame)
        try:
            b, covariance, _ = fit_bradley_terry(wins, systems)
        except AnalysisInputError as exc:
            where = " · ".join(map(str, key.values())) or "all pages"
            notes.append(f"No Bradley-Terry scale for {where}: {exc}.")
            continue
        yield key, systems, wins, b, covariance


def bradley_terry_scale(pages: pd.DataFrame, groupby: Sequence[str] = CELL,
                        confidence: float = 0.95, reference: str | None = None) -> tuple[pd.DataFrame, list[str]]:
    """Bradley-Terry strengths per system and cell from `preference_pages` output.

    Columns: *groupby, system, comparisons (pages with a preference), wins, strength
    (centred log-strength), se, ci_low, ci_high, reference (``reference`` where compared
    in the cell, else the first system in sorted order), strength_vs_reference and
    se_vs_reference (the strength with the reference fixed at 0), participants (who saw
    the system) and warning (intervals from few participants, `analysis.stats.minimums`).
    Cells where the strengths do not exist are left out; the notes say why.
    """
    z = sps.norm.ppf(0.5 + confidence / 2)
    rows, notes = [], []
    for key, systems, wins, b, covariance in _cell_fits(pages, groupby, notes):
        se = np.sqrt(np.diag(covariance))
        r = systems.index(reference) if reference in systems else 0
        se_fixed = np.sqrt(np.maximum(np.diag(covariance) + covariance[r, r] - 2 * covariance[r], 0.0))
        rows.append(pd.DataFrame({**key, "system": systems,
                                  "comparisons": (wins + wins.T).sum(axis=1).astype(int),
                                  "wins": wins.sum(axis=1).astype(int), "strength": b, "se": se,
                                  "ci_low": b - z * se, "ci_high": b + z * se, "reference": systems[r],
                                  "strength_vs_reference": b - b[r], "se_vs_reference": se_fixed}))
    columns = [*groupby, "system", "comparisons", "wins", "strength", "se", "ci_low", "ci_high",
               "reference", "strength_vs_reference", "se_vs_reference"]
    if not rows:
        return pd.DataFrame(columns=[*columns, "participants", "warning"]), notes
    shown = pd.concat([pages[[*groupby, "participant", side]].rename(columns={side: "system"})
                       for side in ("system_left", "system_right")])
    return with_participant_warnings(pd.concat(rows, ignore_index=True), shown, [*groupby, "system"]), notes


def bradley_terry_covariance(pages: pd.DataFrame, groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """The covariance of the centred strengths per cell, one row per ordered pair of
    systems (the diagonal included): *groupby, system_a, system_b, covariance."""
    rows = []
    for key, systems, _, _, covariance in _cell_fits(pages, groupby, []):
        a, b = np.meshgrid(np.arange(len(systems)), np.arange(len(systems)), indexing="ij")
        rows.append(pd.DataFrame({**key, "system_a": np.asarray(systems)[a.ravel()],
                                  "system_b": np.asarray(systems)[b.ravel()], "covariance": covariance.ravel()}))
    columns = [*groupby, "system_a", "system_b", "covariance"]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=columns)
