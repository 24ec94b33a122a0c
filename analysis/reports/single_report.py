"""The single design's report (and optionally motion): build, then write.

`analysis.ratings.report.build_report` hands a table to its design (`analysis.designs`),
which runs every analysis; the single design's calls `build_single_report`. Its results are a `Report` of tidy tables plus the papers'
display tables (the other designs': `analysis.reports.design_report`), with a note for everything
that could not be computed and why. `write_report` turns either into a folder:

    summary.md                    a paragraph per task to paste into a paper, plus notes
    tables/<name>.{csv,md,tex,json}
    figures/<name>.{png,svg}

Single-design reports include the rater- and clip-aware models (crossed LMM, cumulative
link mixed model, rater agreement: `analysis.reports.rater_models`).

The study app calls `build_report` and `write_report` too, and shows the same tables and figures.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import plots
from analysis.stats.correlation import subjective_objective_correlation
from analysis.reports.design_report import (DesignReport, RatingDesign, design_summary_text, p_text,
                                            write_design_report)
from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import (ExclusionRules, apply_exclusions, compared_ratings, exclusion_notes,
                                 exclusion_summary, removed_by_reason)
from analysis.levels import POWER
from analysis.stats.minimums import (INTERVAL_FEW_PARTICIPANTS, cells_for_models, participant_warning_notes,
                               with_participant_warnings)
from analysis.raters.mixed import mixed_model_means
from analysis.reports.metric_agreement import AGREEMENT_CAPTION, agreement_text, clip_metrics, metric_agreement
from analysis.motion.motion_io import SystemClips
from analysis.motion.objective import METRIC_COLUMNS, objective_metrics
from analysis.stats.power import more_ratings_for_power, power_summary
from analysis.reports.rater_models import RaterModels, build_rater_models, rater_models_text, write_rater_models
from analysis.stats.anova import (CELL, anova, comparable_cells, pvalue_matrix, system_means,
                            too_few_ratings, tukey_hsd)
from analysis.reports.tables import (FEW_PARTICIPANTS_MARK, objective_table, pvalue_display, significance_table, slug,
                             write_table)


@dataclass
class Report:
    """Everything a report folder shows, as DataFrames (tidy unless named *_display)."""

    flagged: pd.DataFrame
    exclusions: pd.DataFrame
    removed: pd.DataFrame
    means: pd.DataFrame
    anova: pd.DataFrame
    tukey: pd.DataFrame
    mixed: pd.DataFrame
    significance_display: pd.DataFrame
    pvalues_display: dict[tuple[str, str], pd.DataFrame]
    reference: str | None
    rules: ExclusionRules
    design: RatingDesign
    objective: pd.DataFrame | None = None
    objective_display: pd.DataFrame | None = None
    footstep_curves: pd.DataFrame | None = None
    correlation: pd.DataFrame | None = None
    clip_metrics: pd.DataFrame | None = None  # per clip: system, stimulus, metric, value
    metric_agreement: pd.DataFrame | None = None  # per metric: Kendall's tau with the ratings
    metric_systems: pd.DataFrame | None = None  # per system and metric: its mean metric and mean rating
    power: pd.DataFrame | None = None  # more ratings for 80 % power per pair (analysis.stats.power)
    rater_models: RaterModels | None = None  # crossed LMM, CLMM, agreement (analysis.reports.rater_models)
    notes: list[str] = field(default_factory=list)

    @property
    def analysed(self) -> pd.DataFrame:
        """The ratings that enter the statistics: kept, and of compared systems."""
        return self.flagged[self.flagged["kept"] & self.flagged["system"].isin(self.means["system"])]


def _resolve_reference(reference: str | None, compared: set[str], rated: set[str],
                       rules: ExclusionRules, notes: list[str]) -> str | None:
    if reference is not None:
        if reference not in rated:
            raise AnalysisInputError(
                f"reference system {reference!r} does not exist in the ratings; systems: "
                f"{', '.join(sorted(rated))}")
        if reference not in compared:
            raise AnalysisInputError(
                f"reference system {reference!r} has no kept ratings among the compared systems")
        return reference
    if rules.natural_system in compared:
        return rules.natural_system
    notes.append("No reference system (no NAT ratings and none chosen): Table 2 has no "
                 "significance markers.")
    return None


def build_single_report(ratings: pd.DataFrame, design: RatingDesign, rules: ExclusionRules,
                        reference: str | None, motion: dict[str, SystemClips] | None,
                        foot_joints: Sequence[str] | None, foot_kind: str) -> Report:
    """The single design's report (see `analysis.ratings.report.build_report`, which checks the arguments)."""
    rated = set(ratings["system"].unique())
    flagged = apply_exclusions(ratings, rules, design)
    notes = exclusion_notes(flagged, rules, design)
    kept = compared_ratings(flagged, rules, design)
    if kept.empty:
        raise AnalysisInputError("no ratings are left after the exclusions; nothing to analyse")
    too_few = too_few_ratings(kept)
    usable = kept[~kept.set_index([*CELL, "system"]).index.isin(
        too_few.set_index([*CELL, "system"]).index)]
    notes += [f"Not computed for {r.system} in {r.task} · {r.control_class}: only {r.n} kept "
              "rating (two or more needed)." for r in too_few.itertuples(index=False)]
    if usable.empty:
        raise AnalysisInputError("no system has two or more kept ratings in any cell")
    reference = _resolve_reference(reference, set(usable["system"].unique()), rated, rules, notes)
    means = with_participant_warnings(system_means(usable), usable)
    notes += participant_warning_notes(means)
    comparable, compare_notes = comparable_cells(usable)
    notes += compare_notes
    anova_table = anova(comparable) if len(comparable) else pd.DataFrame()
    tukey_table = tukey_hsd(comparable) if len(comparable) else pd.DataFrame()
    modelled, model_notes = cells_for_models(comparable, "mixed model")
    notes += model_notes
    mixed_table = mixed_model_means(modelled) if len(modelled) else pd.DataFrame()
    power_table = more_ratings_for_power(usable, design, power=POWER)
    rater_models = build_rater_models(comparable, reference) if len(comparable) else None
    notes += rater_models.notes if rater_models else []
    if len(mixed_table) and mixed_table["at_boundary"].any():
        where = mixed_table.loc[mixed_table["at_boundary"], list(CELL)].drop_duplicates()
        notes.append("Mixed model: participant variance estimated at zero in "
                     + "; ".join(" · ".join(map(str, r)) for r in where.itertuples(index=False))
                     + " (the model reduces to the plain means there).")
    if reference is not None:
        for task, cc in sorted(set(map(tuple, means[list(CELL)].to_numpy()))):
            in_cell = means[(means["task"] == task) & (means["control_class"] == cc)]
            if reference not in set(in_cell["system"]):
                notes.append(f"{reference} was not rated in {task} · {cc}: no significance "
                             "markers in that column.")
    pvalues = {}
    if len(tukey_table):
        for (task, cc), pairs in tukey_table.groupby(list(CELL), sort=True):
            pvalues[(task, cc)] = pvalue_display(pvalue_matrix(pairs))
    report = Report(
        flagged=flagged, exclusions=exclusion_summary(flagged), removed=removed_by_reason(flagged),
        means=means, anova=anova_table, tukey=tukey_table, mixed=mixed_table,
        significance_display=significance_table(means, tukey_table, reference, too_few),
        pvalues_display=pvalues, reference=reference, rules=rules, design=design, notes=notes,
        power=power_table, rater_models=rater_models)
    if motion:
        _add_objective(report, motion, foot_joints, foot_kind)
    return report


def _add_objective(report: Report, motion: dict[str, SystemClips],
                   foot_joints: Sequence[str] | None, foot_kind: str) -> None:
    metrics, curves, notes = objective_metrics(motion, foot_joints, foot_kind)
    report.objective = metrics
    report.footstep_curves = curves
    report.objective_display = objective_table(metrics, report.rules.natural_system)
    report.notes += notes
    subjective = report.analysed.groupby("system")["value"].mean()
    report.correlation, corr_notes = subjective_objective_correlation(
        subjective, metrics.set_index("system")[list(METRIC_COLUMNS)])
    report.notes += corr_notes
    report.clip_metrics, clip_notes = clip_metrics(motion, report.rules.natural_system, foot_joints, foot_kind)
    report.metric_agreement, report.metric_systems, agreement_notes = metric_agreement(
        report.clip_metrics, report.analysed)
    report.notes += clip_notes + agreement_notes


def _comparison_text(report: Report, task: str, control_class: str) -> str:
    """One cell's ANOVA and post-hoc result in words."""
    a = report.anova[(report.anova["task"] == task)
                     & (report.anova["control_class"] == control_class)].iloc[0]
    text = (f" In {control_class}, a one-way ANOVA found "
            f"{'a significant' if a.p < 0.05 else 'no significant'} effect of system "
            f"(F({a.df_between}, {a.df_within}) = {a.F:.2f}, {p_text(a.p)}).")
    tukey, ref = report.tukey, report.reference
    pairs = tukey[(tukey["task"] == task) & (tukey["control_class"] == control_class)
                  & ((tukey["system_a"] == ref) | (tukey["system_b"] == ref))]
    if ref is None or pairs.empty:
        return text
    same = sorted(set(pairs.loc[~pairs["reject"], ["system_a", "system_b"]].to_numpy().ravel()) - {ref})
    found = (f"{', '.join(same)} not significantly different from {ref}" if same
             else f"every system significantly different from {ref}")
    return text + f" Tukey HSD post-hoc tests (family-wise error rate 0.05) found {found}."


def summary_text(report: Report | DesignReport) -> str:
    """Paragraphs in the style of MoGlow Sec. 5.2 that a researcher can paste."""
    if isinstance(report, DesignReport):
        return design_summary_text(report)
    rules = report.rules
    out = []
    for row in report.exclusions.itertuples(index=False):
        removed = report.removed[report.removed["task"] == row.task]
        reasons = ", ".join(f"{r.participants} {r.reason}" for r in removed.itertuples(index=False))
        text = (f"**{row.task}.** Of {row.participants_total} participants, "
                f"{row.participants_removed} were removed for failing attention checks"
                f"{f' ({reasons})' if reasons else ''}; {report.design.rule_text(rules)}. "
                f"{row.ratings_collected} ratings were collected; "
                f"{row.discarded_participant} were discarded with the removed participants and "
                f"{row.discarded_early} because they were given before the clip had finished "
                f"playing, leaving {row.ratings_kept} ratings, {row.ratings_per_stimulus_min} to "
                f"{row.ratings_per_stimulus_max} per stimulus.")
        if len(report.anova):
            for control_class in report.anova.loc[report.anova["task"] == row.task, "control_class"]:
                text += _comparison_text(report, row.task, control_class)
        out.append(text)
    if report.reference:
        out.append("Table 2 reports means with 95 % confidence intervals; ** and * mark a "
                   f"significant difference from {report.reference} at p < 0.01 and p < 0.05.")
    if report.rater_models is not None:
        out.append(rater_models_text(report.rater_models))
    if report.metric_agreement is not None and len(report.metric_agreement):
        out.append(agreement_text(report.metric_agreement))
    if report.power is not None and len(report.power):
        out.append(power_summary(report.power, power=POWER))
    return "\n\n".join(out) + "\n"


def report_figures(report: Report | DesignReport) -> dict[str, Figure]:
    """The figures of the ratings by file name (the objective metrics' are the folder's own):
    the single design's mean ratings with CIs on the rating scale and the rating
    distributions, the other designs' ``design_figures``."""
    if isinstance(report, DesignReport):
        return report.design.figures(report)
    # A system rated once in a cell has no interval and no test, but both figures show it.
    kept = compared_ratings(report.flagged, report.rules, report.design)
    singles = kept.merge(too_few_ratings(kept)[[*CELL, "system"]], on=[*CELL, "system"])
    return {"means_ci": plots.means_plot(report.means, report.reference, plots.rating_scale(kept), singles),
            "rating_distributions": plots.distribution_plot(kept, report.reference)}


def write_report(report: Report | DesignReport, folder: str | Path) -> list[Path]:
    """Write the report folder (tables, figures, summary.md); return the files written."""
    if isinstance(report, DesignReport):
        return write_design_report(report, folder)
    folder = Path(folder)
    tables, figures = folder / "tables", folder / "figures"
    written = []
    tidy = {"exclusions": report.exclusions, "excluded_participants": report.removed,
            "system_means": report.means, "anova": report.anova, "tukey_hsd": report.tukey,
            "mixed_model_means": report.mixed, "power_more_ratings": report.power}
    for name, table in tidy.items():
        if table is not None and len(table):
            written += write_table(table, tables, name)
    caption = "Mean ratings ± 95 % CI per system (MoGlow Table 2 layout)"
    cells = report.significance_display.astype(str)
    if cells.apply(lambda column: column.str.endswith(FEW_PARTICIPANTS_MARK)).to_numpy().any():
        caption += (f"; {FEW_PARTICIPANTS_MARK.strip()}: an interval from fewer than "
                    f"{INTERVAL_FEW_PARTICIPANTS} participants")
    written += write_table(report.significance_display, tables, "table2_significance", caption=caption + ".")
    for (task, cc), matrix in report.pvalues_display.items():
        written += write_table(matrix, tables, f"pvalues_{slug(task, cc)}",
                               caption=f"Tukey HSD adjusted p-values, {task} · {cc}.")
    if report.rater_models is not None:
        written += write_rater_models(report.rater_models, folder)
    for name, figure in report_figures(report).items():
        written += plots.save_figure(figure, figures, name)
    if report.objective is not None:
        written += write_table(report.objective, tables, "objective_metrics")
        written += write_table(report.objective_display, tables, "table3_objective",
                               caption="Objective metrics (MoGlow Table 3 layout); marked: closest to NAT.")
        written += write_table(report.footstep_curves, tables, "footstep_curves",
                               formats=("csv", "json"))
        if len(report.correlation):
            written += write_table(report.correlation, tables, "correlation")
        written += write_table(report.clip_metrics, tables, "clip_metrics", formats=("csv", "json"))
        if len(report.metric_agreement):
            written += write_table(report.metric_agreement, tables, "metric_agreement", caption=AGREEMENT_CAPTION)
            written += plots.save_figure(plots.metric_agreement_plot(report.metric_agreement, report.metric_systems,
                                                                     report.rules.natural_system),
                                         figures, "metric_agreement")
        written += plots.save_figure(plots.footstep_plot(report.footstep_curves,
                                                         report.rules.natural_system),
                                     figures, "footstep_curves")
    notes = "".join(f"- {n}\n" for n in report.notes) or "- None: everything was computed.\n"
    summary = folder / "summary.md"
    summary.write_text("# Summary\n\n" + summary_text(report)
                       + "\n## Notes (what was not computed, and why)\n\n" + notes, encoding="utf-8")
    return [summary, *written]
