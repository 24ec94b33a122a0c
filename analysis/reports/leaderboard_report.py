"""The leaderboard of a pairwise study as a report: its tables, heat maps and a paragraph
saying how it was computed (`analysis.rankings.leaderboard` holds the statistics).

Tables: ``leaderboard`` (rank, Elo, 95 % interval, pages won, lost and tied per system),
``battles`` (per ordered pair: pages, wins, ties, win fraction) and ``side_bias`` (the
share of stated preferences that went to the left clip, exact binomial test of 1/2;
`analysis.stats.preferences.side_bias`). Figures: ``win_fraction`` and ``battles`` heat maps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from analysis.reports import plots
from analysis.rankings.leaderboard import (BRADLEY_TERRY, CLEAR, DAVIDSON, INTERVAL_WARNING_PARTICIPANTS,
                                  PLAIN_WIN_WEIGHT, RESAMPLES, SLIGHT, TIE_WEIGHT, WINS_PER_DEGREE, battles,
                                  leaderboard)
from analysis.reports.leaderboard_plots import heat_map_plot
from analysis.stats.preferences import side_bias
from analysis.stats.anova import CELL
from analysis.reports.tables import write_table


@dataclass
class LeaderboardReport:
    """A pairwise study's leaderboard, as tidy tables, with how it was computed."""

    board: pd.DataFrame
    battles: pd.DataFrame
    side_bias: pd.DataFrame
    participants: pd.DataFrame  # per cell: participants whose pages entered the fit
    model: str
    resamples: int
    seed: int
    confidence: float
    notes: list[str] = field(default_factory=list)


def build_leaderboard(kept: pd.DataFrame, anchor: str | None = None, model: str = BRADLEY_TERRY,
                      resamples: int = RESAMPLES, seed: int = 0, natural: str = "NAT",
                      confidence: float = 0.95, groupby: Sequence[str] = CELL) -> LeaderboardReport:
    """The leaderboard, heat maps' numbers and side-bias test of a pairwise table's
    compared rows (kept, attention-check pages removed: `analysis.ratings.exclusions.compared_ratings`)."""
    board, notes = leaderboard(kept, anchor, model, resamples, seed, confidence, natural, groupby)
    participants = kept.groupby(list(groupby))["participant"].nunique().rename("participants").reset_index()
    return LeaderboardReport(board, battles(kept, groupby), side_bias(kept, groupby, confidence),
                             participants, model, resamples, seed, confidence, notes)


def _p_text(p: float) -> str:
    return "p < .001" if p < 0.001 else f"p = {p:.3f}".replace("0.", ".", 1)


def method_text(report: LeaderboardReport) -> str:
    """How the votes were weighted and which model was fitted, in words."""
    weights = (f"a preference of strength k counts {WINS_PER_DEGREE:g}k wins of the preferred system "
               f"(GENEA's slight preference, strength {SLIGHT}, {WINS_PER_DEGREE * SLIGHT:g} and clear one, "
               f"strength {CLEAR}, {WINS_PER_DEGREE * CLEAR:g}; each further degree {WINS_PER_DEGREE:g} more), "
               f"and a preference given without a strength (a plain left / right answer) counts as "
               f"clear ({PLAIN_WIN_WEIGHT:g})")
    if report.model == DAVIDSON:
        return (f"Davidson's model, in which a tie is an outcome of its own (P(tie) = nu "
                f"sqrt(pi_i pi_j) / (pi_i + pi_j + nu sqrt(pi_i pi_j))): {weights}; a page "
                f"without preference counts {2 * TIE_WEIGHT:g} ties")
    return (f"a weighted Bradley-Terry model fitted by weighted logistic regression: {weights}; "
            f"a page without preference counts {TIE_WEIGHT:g} win for each side")


def leaderboard_text(report: LeaderboardReport) -> str:
    """A paragraph per cell to paste into a paper: the model, the scale and its intervals,
    the systems in order with their intervals, and the side-bias test."""
    out = []
    for key, board in report.board.groupby(list(CELL), sort=True):
        task, cc = key
        where = report.participants[(report.participants["task"] == task)
                                    & (report.participants["control_class"] == cc)]
        anchor = board["anchor"].iloc[0]
        origin = origin_text(board)
        nu = (f" (tie parameter nu = {board['tie_parameter'].iloc[0]:.3f})"
              if report.model == DAVIDSON else "")
        systems = ", ".join(
            f"{r.system} {r.elo:.0f} (anchor)" if r.system == anchor
            else f"{r.system} {r.elo:.0f} [{r.ci_low:.0f}, {r.ci_high:.0f}]"
            for r in board.itertuples(index=False))
        text = (f"**Leaderboard, {task} · {cc}.** {int(board['pages'].sum()) // 2} pages from "
                f"{int(where['participants'].iloc[0])} participants were fitted with "
                f"{method_text(report)}{nu}. On the Elo scale (1000 + 400 b / ln 10, so 400 points "
                f"are odds of 10 to 1) with {origin} and {report.confidence * 100:g} % percentile "
                f"intervals from {report.resamples:,} bootstrap resamples of the participants "
                f"(seed {report.seed}): {systems}.")
        if _rough(board).any():
            text += (f" With fewer than {INTERVAL_WARNING_PARTICIPANTS} participants these intervals "
                     "understate the uncertainty: read them as rough.")
        bias = report.side_bias[(report.side_bias["task"] == task) & (report.side_bias["control_class"] == cc)]
        if len(bias) and bias["n_decided"].iloc[0]:
            b = bias.iloc[0]
            text += (f" The left clip was preferred on {b['left_share'] * 100:.0f} % of the "
                     f"{int(b['n_decided'])} pages with a preference (exact binomial test of 50 %: "
                     f"{_p_text(b['p'])}).")
        out.append(text)
    return "\n\n".join(out)


def _rough(board: pd.DataFrame) -> pd.Series:
    """The rows whose intervals come from fewer than INTERVAL_WARNING_PARTICIPANTS participants."""
    return board["ci_low"].notna() & (board["participants"] < INTERVAL_WARNING_PARTICIPANTS)


def origin_text(board: pd.DataFrame) -> str:
    """Where a leaderboard's Elo scale is fixed: its anchor (or the systems' mean) and origin."""
    fixed = sorted({f"{a} at {o:g}" if a != "mean" else f"the systems' mean at {o:g}"
                    for a, o in zip(board["anchor"], board["origin"])})
    if not fixed:
        return "no anchor (no cell was fitted)"
    return fixed[0] if len(fixed) == 1 else f"{'; '.join(fixed)} (per cell: its anchor column)"


def leaderboard_tables(report: LeaderboardReport) -> dict[str, tuple[str, pd.DataFrame]]:
    """File name -> (title, table) of the leaderboard and its battles."""
    few = (f"; intervals from fewer than {INTERVAL_WARNING_PARTICIPANTS} participants are rough "
           "(warning)" if _rough(report.board).any() else "")
    return {"leaderboard": (f"Leaderboard ({report.model}): Elo with {origin_text(report.board)}, 400 points "
                            f"odds of 10 to 1, and {report.confidence * 100:g} % bootstrap intervals over "
                            f"participants{few}", report.board),
            "battles": ("Pages per ordered pair of systems: battles, wins of the row system, ties, "
                        "and its share of the decided pages", report.battles)}


def write_heat_maps(report: LeaderboardReport, figures: str | Path) -> list[Path]:
    """The win-fraction and battle-count heat maps as figures/<name>.{png,svg}."""
    if report.battles.empty:
        return []
    return [path for value in ("win_fraction", "battles")
            for path in plots.save_figure(heat_map_plot(report.battles, report.board, value), figures, value)]


def write_leaderboard(report: LeaderboardReport, folder: str | Path) -> list[Path]:
    """Write the tables (tables/<name>.{csv,md,tex,json}) and heat maps (figures/<name>.{png,svg})."""
    folder = Path(folder)
    tables = {**leaderboard_tables(report),
              "side_bias": ("Share of stated preferences for the left clip", report.side_bias)}
    written = [path for name, (title, table) in tables.items() if len(table)
               for path in write_table(table, folder / "tables", name, caption=f"{title}.")]
    return written + write_heat_maps(report, folder / "figures")
