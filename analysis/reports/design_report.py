"""The report of a design with several clips on a page (side-by-side, pairwise,
appropriateness): build, then write, as `analysis.reports.single_report` does for the single design.

Every such report applies the exclusions, keeps the compared ratings and finds the
reference system (NAT where compared) the same way; the table's design object
(`analysis.designs`) then adds its tables, and says its summary sentences and draws its
figures. The folder layout is the single design's: summary.md,
tables/<name>.{csv,md,tex,json}, figures/<name>.{png,svg}. The helpers below the report
(`power_table`, `exclusion_sentence`, `p_text`, `in_cell`, `interval_text`) are the
designs' shared wording.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import plots
from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import (ExclusionRules, RuledDesign, apply_exclusions, compared_ratings, exclusion_notes,
                                 exclusion_summary, removed_by_reason)
from analysis.reports.leaderboard_report import LeaderboardReport, leaderboard_text
from analysis.levels import ALPHA, POWER
from analysis.stats.power import PoweredDesign, more_ratings_for_power, power_summary
from analysis.reports.rater_models import RaterModels, rater_models_text
from analysis.reports.reasons import CAPTION as REASONS_CAPTION, has_reasons, reason_counts, reasons_plot
from analysis.stats.anova import CELL
from analysis.reports.tables import write_table


class RatingDesign(RuledDesign, PoweredDesign, Protocol):
    """What a report asks of the table's design, handed in by the design itself
    (`analysis.designs.base.RatingDesign`, which this report sits below)."""

    name: str
    main_table: str  # the table whose cells the summary walks

    def rule_text(self, rules: ExclusionRules, scale: tuple[int, int] | None = None) -> str: ...

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None: ...

    def exclusion_sentence(self, report: DesignReport, row) -> str: ...

    def cell_sentence(self, report: DesignReport, task: str, control_class: str) -> str: ...

    def figures(self, report: DesignReport) -> dict[str, Figure]: ...

    def write_figures(self, report: DesignReport, folder: Path) -> list[Path]: ...



@dataclass
class DesignReport:
    """Everything a side-by-side, pairwise or appropriateness report folder shows, as tidy
    DataFrames.

    ``tables`` maps a file name to (title, table), in the order the report shows them.
    """

    design: RatingDesign
    flagged: pd.DataFrame
    exclusions: pd.DataFrame
    removed: pd.DataFrame
    tables: dict[str, tuple[str, pd.DataFrame]]
    reference: str | None
    rules: ExclusionRules
    alpha: float
    notes: list[str] = field(default_factory=list)
    continuity_correction: bool = False  # of the Wilcoxon tests' normal approximation
    leaderboard: LeaderboardReport | None = None  # pairwise
    rater_models: RaterModels | None = None  # side-by-side

    def table(self, name: str) -> pd.DataFrame:
        return self.tables[name][1]


def build_design_report(ratings: pd.DataFrame, design: RatingDesign, reference: str | None = None,
                        rules: ExclusionRules = ExclusionRules(), alpha: float = ALPHA,
                        continuity_correction: bool = False) -> DesignReport:
    """Run the analysis of a validated ratings table of ``design``; ``continuity_correction``
    applies to the Wilcoxon tests' normal approximation."""
    if reference is not None and reference not in set(ratings["system"]):
        raise AnalysisInputError(
            f"reference system {reference!r} does not exist in the ratings; systems: "
            f"{', '.join(sorted(set(ratings['system'])))}")
    flagged = apply_exclusions(ratings, rules, design)
    notes = exclusion_notes(flagged, rules, design)
    kept = compared_ratings(flagged, rules, design)
    if kept.empty:
        raise AnalysisInputError("no ratings are left after the exclusions; nothing to analyse")
    if reference is None and rules.natural_system in set(kept["system"]):
        reference = rules.natural_system
    report = DesignReport(design, flagged, exclusion_summary(flagged), removed_by_reason(flagged), {},
                          reference, rules, alpha, notes, continuity_correction)
    design.analyse(report, kept)
    if has_reasons(kept):  # pairwise and side-by-side pages that asked why
        counts, reason_notes = reason_counts(kept)
        report.tables["reasons"] = (REASONS_CAPTION, counts)
        report.notes += reason_notes
    return report


def power_table(kept: pd.DataFrame, design: PoweredDesign, alpha: float) -> tuple[str, pd.DataFrame]:
    """The report's table of the ratings each pair of ``design`` needs for `POWER` (`analysis.stats.power`)."""
    return (f"Ratings needed for {POWER * 100:g} % power per pair", more_ratings_for_power(kept, design, alpha, POWER))


def p_text(p: float) -> str:
    return "p < .001" if p < 0.001 else f"p = {p:.3f}".replace("0.", ".", 1)


def in_cell(table: pd.DataFrame, task: str, cc: str) -> pd.DataFrame:
    return table[(table["task"] == task) & (table["control_class"] == cc)] if len(table) else table


def interval_text(value: float, low: float, high: float, decimals: int, missing: str = "n < 6") -> str:
    """``value [low, high]``, or ``value [missing]`` (why there is no interval) where low is missing."""
    bounds = missing if pd.isna(low) else f"{low:.{decimals}f}, {high:.{decimals}f}"
    return f"{value:.{decimals}f} [{bounds}]"


def exclusion_sentence(report: DesignReport, row, rule: str, counted: str, discarded: int, early: int,
                       kept: int) -> str:
    """One task's exclusions in words: ``row`` of ``report.exclusions``, the design's ``rule``
    in words, what was ``counted`` as collected, and how many of those were ``discarded``
    with the removed participants, discarded as ``early`` answers and ``kept``."""
    removed = report.removed[report.removed["task"] == row.task]
    reasons = ", ".join(f"{r.participants} {r.reason}" for r in removed.itertuples(index=False))
    return (f"**{row.task}.** Of {row.participants_total} participants, {row.participants_removed} "
            f"were removed for failing attention checks{f' ({reasons})' if reasons else ''}; "
            f"{rule}. {counted}; {discarded} were discarded with the removed participants "
            f"and {early} because an answer came before a clip had finished playing, leaving "
            f"{kept}.")


def design_summary_text(report: DesignReport) -> str:
    """Paragraphs a researcher can paste: exclusions and the tests' findings per task."""
    design = report.design
    cells = report.table(design.main_table)[list(CELL)].drop_duplicates().sort_values(list(CELL))
    out = []
    for row in report.exclusions.itertuples(index=False):
        text = design.exclusion_sentence(report, row)
        for cc in cells.loc[cells["task"] == row.task, "control_class"]:
            text += design.cell_sentence(report, row.task, cc)
        out.append(text)
    if report.leaderboard is not None:
        out.append(leaderboard_text(report.leaderboard))
    if report.rater_models is not None:
        out.append(rater_models_text(report.rater_models))
    if "power_more_ratings" in report.tables:
        out.append(power_summary(report.table("power_more_ratings"), report.alpha, POWER))
    return "\n\n".join(p for p in out if p) + "\n"


def design_figures(report: DesignReport) -> dict[str, Figure]:
    """The report's figures by file name, as its design draws them."""
    return report.design.figures(report)


def write_design_report(report: DesignReport, folder: str | Path) -> list[Path]:
    """Write the report folder (tables, figures, summary.md); return the files written."""
    folder = Path(folder)
    tables, figures = folder / "tables", folder / "figures"
    written = []
    for name, table in (("exclusions", report.exclusions), ("excluded_participants", report.removed)):
        if len(table):
            written += write_table(table, tables, name)
    for name, (title, table) in report.tables.items():
        if len(table):
            written += write_table(table, tables, name, caption=f"{title}.")
    written += report.design.write_figures(report, figures)
    if "reasons" in report.tables and len(report.table("reasons")):  # its table is written with the others
        written += plots.save_figure(reasons_plot(report.table("reasons")), figures, "reasons")
    notes = "".join(f"- {n}\n" for n in report.notes) or "- None: everything was computed.\n"
    summary = folder / "summary.md"
    summary.write_text("# Summary\n\n" + design_summary_text(report)
                       + "\n## Notes (what was not computed, and why)\n\n" + notes, encoding="utf-8")
    return [summary, *written]
