"""The side-by-side design: one page shows several systems' clips for the same control, each
rated on the scale (HEMVIP / MUSHRA, as in the GENEA challenges).

Its table adds ``page`` (and optionally ``position``) to the minimal schema; its rules are
the rated clips' defaults of `RatingDesign`, applied clip by clip. Its report (GENEA's
analysis of HEMVIP pages): per system the median and mean with 95 % intervals, two-sided
Wilcoxon signed-rank tests on the per-page differences of every pair, Holm-Bonferroni
corrected per task x control class, the significance matrix, the random-intercept mixed
model on the slider values, the rater- and clip-aware models with rater agreement
(`analysis.reports.rater_models`) and the ratings needed for 80 % power per pair.
"""

from __future__ import annotations


import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import design_plots, plots
from analysis.reports.design_report import (DesignReport, exclusion_sentence, in_cell, interval_text, power_table)
from analysis.designs.base import RatingDesign
from analysis.pages import PAGE, first_row, labels, no_system_twice_on_a_page, page_name, positive_integers
from analysis.errors import AnalysisInputError
from analysis.raters.mixed import mixed_model_means
from analysis.stats.power import pages_for_page_effect, pairs_of, side_by_side_pairs
from analysis.reports.rater_models import build_rater_models
from analysis.stats.within_page import median_and_mean, signed_rank_pairs
from analysis.stats.anova import CELL, comparable_cells, too_few_ratings
from analysis.reports.tables import system_order


class SideBySide(RatingDesign):
    name = "side-by-side"

    def required_columns(self, minimal: tuple[str, ...]) -> tuple[str, ...]:
        return (*minimal, "page")

    def check_pages(self, df: pd.DataFrame) -> pd.DataFrame:
        """Returns the table with ``position`` as integers."""
        df = df.copy()
        df["page"] = labels(df["page"], "page")
        if "position" in df.columns:
            df["position"] = positive_integers(df["position"], "position", allow_empty=False)
            shared = df.duplicated([*PAGE, "position"], keep=False)
            if shared.any():
                raise AnalysisInputError(
                    f"two clips share position {df.loc[shared, 'position'].iloc[0]} on page "
                    f"{page_name(df, shared)} (first at row {first_row(shared)})")
        no_system_twice_on_a_page(df)
        return df

    def power_pairs(self, frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
        return side_by_side_pairs(frame, alpha, power)

    planned_tests = (
        "per task and control class, each system's median and mean rating with 95 % intervals",
        "two-sided Wilcoxon signed-rank tests on the per-page differences of every pair of systems, "
        "Holm-Bonferroni corrected per task and control class, and their significance matrix",
        "a linear mixed model of the ratings with a random intercept per participant",
        "the rater- and clip-aware models and the raters' agreement",
        "the pages needed for 80 % power per pair of systems",
    )
    effect_words = "a standardised mean difference of two systems' ratings on the same page (d of the per-page differences)"
    planned_unit = "pages"
    units_per_pair = True

    def planned_units(self, effect: float, systems: int, alpha: float, power: float) -> int:
        return pages_for_page_effect(effect, pairs_of(systems), alpha, power)

    # The report.

    main_table = "system_medians_means"

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None:
        notes = report.notes
        too_few = too_few_ratings(kept)
        notes += [f"Not computed for {r.system} in {r.task} · {r.control_class}: only {r.n} kept "
                  "rating (two or more needed)." for r in too_few.itertuples(index=False)]
        usable = kept[~kept.set_index([*CELL, "system"]).index.isin(
            too_few.set_index([*CELL, "system"]).index)]
        if usable.empty:
            raise AnalysisInputError("no system has two or more kept ratings in any cell")
        pairs = signed_rank_pairs(usable, alpha=report.alpha, continuity=report.continuity_correction)
        untested = pairs[pairs["method"] == "not computed"] if len(pairs) else pairs
        notes += [f"No Wilcoxon test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: "
                  "no page rated them differently." for r in untested.itertuples(index=False)]
        comparable, _ = comparable_cells(usable)
        left_out = sorted(set(map(tuple, usable[list(CELL)].drop_duplicates().to_numpy()))
                          - set(map(tuple, comparable[list(CELL)].drop_duplicates().to_numpy())))
        notes += [f"No mixed model for {task} · {cc}: fewer than two systems, or no rating "
                  "variation within any system." for task, cc in left_out]
        mixed = mixed_model_means(comparable) if len(comparable) else pd.DataFrame()
        report.tables.update({
            "system_medians_means": ("Median and mean rating per system with 95 % intervals",
                                     median_and_mean(usable)),
            "wilcoxon_pairs": ("Wilcoxon signed-rank tests on per-page differences, Holm corrected", pairs),
            "mixed_model_means": ("Linear mixed model (participant random intercept)", mixed),
        })
        reference = report.reference if report.reference in set(kept["system"]) else None
        report.rater_models = build_rater_models(kept, reference, report.alpha)
        report.tables.update(report.rater_models.tables())
        notes += report.rater_models.notes
        report.tables["power_more_ratings"] = power_table(kept, self, report.alpha)

    def exclusion_sentence(self, report: DesignReport, row) -> str:
        in_task = report.flagged[report.flagged["task"] == row.task]
        scale = (int(in_task["scale_min"].iloc[0]), int(in_task["scale_max"].iloc[0]))
        counted = f"{row.ratings_collected} ratings on {in_task.groupby(list(PAGE)).ngroups} pages were collected"
        return exclusion_sentence(report, row, self.rule_text(report.rules, scale), counted,
                                  row.discarded_participant, row.discarded_early, row.ratings_kept)

    def cell_sentence(self, report: DesignReport, task: str, cc: str) -> str:
        scores = in_cell(report.table("system_medians_means"), task, cc).sort_values(
            ["median", "mean"], ascending=False)
        text = (f" In {cc}, the median ratings [95 % CI] were "
                + ", ".join(f"{r.system} {interval_text(r.median, r.median_ci_low, r.median_ci_high, 0)}"
                            for r in scores.itertuples(index=False))
                + " and the means "
                + ", ".join(f"{r.system} {interval_text(r.mean, r.ci_low, r.ci_high, 1)}"
                            for r in scores.itertuples(index=False)) + ".")
        pairs = in_cell(report.table("wilcoxon_pairs"), task, cc)
        pairs = pairs[pairs["p"].notna()] if len(pairs) else pairs
        if pairs.empty:
            return text
        higher = [f"{r.higher} > {r.system_b if r.higher == r.system_a else r.system_a}"
                  for r in pairs[pairs["reject"]].itertuples(index=False)]
        same = [f"{r.system_a} and {r.system_b}" for r in pairs[~pairs["reject"]].itertuples(index=False)]
        correction = "with" if report.continuity_correction else "without"
        text += (f" Two-sided Wilcoxon signed-rank tests on the per-page rating differences "
                 f"of each pair of systems (exact up to 50 pages without tied differences, else the "
                 f"normal approximation {correction} continuity correction), Holm-Bonferroni "
                 f"corrected over the {len(pairs)} pairs "
                 f"(family-wise α = {report.alpha:g}), found {len(higher)} significant difference(s)")
        text += f", the first system rated higher: {'; '.join(higher)}" if higher else ""
        text += f". No significant difference between {'; '.join(same)}." if same else "."
        return text

    def figures(self, report: DesignReport) -> dict[str, Figure]:
        """The median and mean per system on the rating scale, and the significance matrix."""
        scores = report.table("system_medians_means")
        order = system_order(scores["system"].unique(), report.reference)
        figures = {"median_mean_ci": design_plots.scale_plot(
            scores, [("median", "median", "median_ci_low", "median_ci_high"), ("mean", "mean", "ci_low", "ci_high")],
            "rating (95 % interval)", order, plots.rating_scale(report.flagged))}
        if len(report.table("wilcoxon_pairs")):
            figures["significance_matrix"] = design_plots.significance_matrix_plot(report.table("wilcoxon_pairs"), scores)
        return figures
