"""What a board shows publicly, and nothing more: its systems' table (rank, Elo, interval,
votes, since when), the win-rate heat map, the rounds it rests on (names, dates, in or out
of the fit) and its anchor and origin; its CSV is the same table.

Nothing here names a participant: no participant ids or platform ids, no per-vote rows, no
free text of participants. Counts (votes, participants) are totals. The researcher's board
page shows this same context as its preview, so what is public is what they see there.
"""

from __future__ import annotations

import base64
import csv
import io

import pandas as pd

from analysis.reports.leaderboard_plots import heat_map_plot
from analysis.reports.leaderboard_report import method_text, origin_text
from analysis.reports.plots import plt
from analysis.reports.tables import spreadsheet_safe
from studyapp.leaderboards.fit import SAME_SYSTEM_RULE, BoardFit

PUBLIC_COLUMNS = ("rank", "system", "elo", "ci_low", "ci_high", "pages", "wins", "losses", "ties", "first_round",
                  "first_round_name", "since", "rounds", "anchor", "origin", "model", "resamples_used",
                  "participants", "few_participants")
HEADERS = {"rank": "Rank", "system": "System", "elo": "Elo", "ci_low": "95 % low", "ci_high": "95 % high",
           "pages": "Votes (pages)", "wins": "Won", "losses": "Lost", "ties": "No preference",
           "first_round": "Since round", "first_round_name": "Round's name", "since": "First vote",
           "rounds": "Rounds", "anchor": "Anchor", "origin": "Origin", "model": "Model",
           "resamples_used": "Resamples used", "participants": "Participants (all rounds)",
           "few_participants": "Few participants"}


def public_table(fit: BoardFit) -> pd.DataFrame:
    """The board's systems, best first, in ``PUBLIC_COLUMNS`` (empty without a fit)."""
    if fit.report is None:
        return pd.DataFrame(columns=list(PUBLIC_COLUMNS))
    return fit.systems[list(PUBLIC_COLUMNS)].reset_index(drop=True)


def board_csv(fit: BoardFit) -> bytes:
    """`public_table` as CSV (text a spreadsheet would run as a formula gets a leading apostrophe)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(PUBLIC_COLUMNS)
    for row in public_table(fit).itertuples(index=False):
        writer.writerow([spreadsheet_safe("" if pd.isna(v) else (f"{v:.4f}" if isinstance(v, float) else v))
                         for v in row])
    return buffer.getvalue().encode()


def heat_map_png(fit: BoardFit) -> str:
    """The win-rate matrix (share of decided pages the row system won) as a PNG data URL, or ""."""
    if fit.report is None or fit.report.battles.empty:
        return ""
    figure = heat_map_plot(fit.report.battles, fit.report.board, "win_fraction")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    plt.close(figure)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode()


def _row(row: pd.Series) -> dict:
    def number(value, digits=0):
        return "" if pd.isna(value) else f"{value:.{digits}f}"
    return {"rank": int(row["rank"]), "system": row["system"], "elo": number(row["elo"]),
            "ci_low": number(row["ci_low"]), "ci_high": number(row["ci_high"]), "pages": int(row["pages"]),
            "wins": int(row["wins"]), "losses": int(row["losses"]), "ties": int(row["ties"]),
            "first_round": int(row["first_round"]), "first_round_name": row["first_round_name"],
            "since": row["since"], "is_anchor": row["system"] == row["anchor"]}


def board_context(fit: BoardFit) -> dict:
    """The template context of the public board (`studyapp/leaderboard/_board.html`)."""
    table = public_table(fit)
    report = fit.report
    return {
        "board": fit.board,
        "systems": [_row(row) for _, row in table.iterrows()],
        "rounds": [{"number": r.number, "name": r.name, "in_fit": r.in_fit, "left_out_because": r.left_out_because,
                    "pages": r.pages, "first_vote": r.first_vote, "last_vote": r.last_vote,
                    "new_systems": r.new_systems, "systems": r.systems} for r in fit.rounds],
        "scale": (f"Elo with {origin_text(report.board)}; 400 points are odds of 10 to 1; "
                  f"{report.confidence * 100:g} % intervals from {report.resamples:,} bootstrap resamples of the "
                  f"participants" if report is not None else ""),
        "method": method_text(report) if report is not None else "",
        "same_system_rule": SAME_SYSTEM_RULE,
        "participants": int(table["participants"].iloc[0]) if len(table) else 0,
        "few_participants": bool(table["few_participants"].any()) if len(table) else False,
        "heat_map": heat_map_png(fit),
        "notes": fit.notes,
    }
