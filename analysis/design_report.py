"""The report of a side-by-side, pairwise or appropriateness study: build, then write (as
`analysis.report` does for the single design, which dispatches here on the table's design).

Side-by-side (GENEA's analysis of HEMVIP pages): exclusions, per system the median and
mean with 95 % intervals, two-sided Wilcoxon signed-rank tests on the per-page
differences of every pair, Holm-Bonferroni corrected per task x control class, the
significance matrix, the random-intercept mixed model on the slider values, and the
rater- and clip-aware models with rater agreement (`analysis.rater_models`).

Pairwise: exclusions, per pair the preference share with its Wilson interval and the
share of "no preference", exact two-sided binomial (sign) tests on the pages with a
preference, Holm-Bonferroni corrected, a Bradley-Terry scale with 95 % intervals, a
check of the raters' side bias, and the leaderboard (`analysis.leaderboard_report`:
graded votes weighted, Elo with bootstrap intervals, win-fraction and battle heat maps).

Appropriateness (`analysis.appropriateness`): exclusions, per system the share of pages
preferring the matched clip (ties split, Wilson interval) with a sign test of 50 %, the
mean appropriateness score with a bootstrap interval over participants, Wilcoxon tests of
every pair of systems' scores, Holm corrected, and the raters' side bias.

Side-by-side and pairwise: how many more ratings would give 80 % power per pair
(`analysis.power`). All: a paragraph per task to paste into a paper. The folder layout is the single design's:
summary.md, tables/<name>.{csv,md,tex,json}, figures/<name>.{png,svg}.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from analysis import design_plots, plots
from analysis.appropriateness import appropriateness_scores, matched_preference, score_pairs
from analysis.bradley_terry import bradley_terry_covariance, bradley_terry_scale
from analysis.designs import APPROPRIATENESS, PAGE, PAIRWISE, PREFERENCE_DESIGNS, SIDE_BY_SIDE, table_design
from analysis.errors import AnalysisInputError
from analysis.exclusions import (ExclusionRules, apply_exclusions, attention_rule_text,
                                 compared_ratings, exclusion_notes, exclusion_summary,
                                 removed_by_reason)
from analysis.leaderboard_report import (LeaderboardReport, build_leaderboard, leaderboard_tables,
                                         leaderboard_text, write_heat_maps)
from analysis.mixed import mixed_model_means
from analysis.pairwise import preference_pages, preference_pairs, side_bias
from analysis.power import more_ratings_for_power, power_summary
from analysis.rater_models import RaterModels, build_rater_models, rater_models_text
from analysis.side_by_side import median_and_mean, signed_rank_pairs
from analysis.stats import CELL, comparable_cells, too_few_ratings
from analysis.tables import system_order, write_table

POWER = 0.8


@dataclass
class DesignReport:
    """Everything a side-by-side or pairwise report folder shows, as tidy DataFrames.

    ``tables`` maps a file name to (title, table), in the order the report shows them.
    """

    design: str
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


def build_design_report(ratings: pd.DataFrame, reference: str | None = None,
                        rules: ExclusionRules = ExclusionRules(),
                        compare_attention_checks: bool = False,
                        alpha: float = 0.05, continuity_correction: bool = False) -> DesignReport:
    """Run the analysis of a validated side-by-side, pairwise or appropriateness ratings
    table; ``continuity_correction`` applies to the Wilcoxon tests' normal approximation."""
    design = table_design(ratings)
    if design not in (SIDE_BY_SIDE, PAIRWISE, APPROPRIATENESS):
        raise AnalysisInputError(f"build_design_report analyses side-by-side, pairwise and "
                                 f"appropriateness tables; this one is {design}")
    if reference is not None and reference not in set(ratings["system"]):
        raise AnalysisInputError(
            f"reference system {reference!r} does not exist in the ratings; systems: "
            f"{', '.join(sorted(set(ratings['system'])))}")
    if compare_attention_checks:
        rules = replace(rules, attention_rule=False)
    flagged = apply_exclusions(ratings, rules)
    notes = exclusion_notes(flagged, rules)
    kept = compared_ratings(flagged, rules)
    if kept.empty:
        raise AnalysisInputError("no ratings are left after the exclusions; nothing to analyse")
    if reference is None and rules.natural_system in set(kept["system"]):
        reference = rules.natural_system
    if design == SIDE_BY_SIDE:
        tables = _side_by_side_tables(kept, alpha, notes, continuity_correction)
    elif design == PAIRWISE:
        tables = _pairwise_tables(kept, alpha, notes, reference)
    else:
        tables = _appropriateness_tables(kept, alpha, notes)
    leaderboard = rater_models = None
    if design == SIDE_BY_SIDE:
        rater_models = build_rater_models(kept, reference if reference in set(kept["system"]) else None, alpha)
        tables.update(rater_models.tables())
        notes += rater_models.notes
    if design == PAIRWISE:
        leaderboard = build_leaderboard(kept, reference if reference in set(kept["system"]) else None,
                                        natural=rules.natural_system)
        tables.update(leaderboard_tables(leaderboard))
        notes += leaderboard.notes
    if design != APPROPRIATENESS:  # its systems are not compared on shared pages
        power = more_ratings_for_power(kept, alpha, POWER)
        tables["power_more_ratings"] = (f"Ratings needed for {POWER * 100:g} % power per pair", power)
    return DesignReport(design, flagged, exclusion_summary(flagged), removed_by_reason(flagged),
                        tables, reference, rules, alpha, notes, continuity_correction, leaderboard,
                        rater_models)


def _side_by_side_tables(kept: pd.DataFrame, alpha: float, notes: list[str],
                         continuity_correction: bool) -> dict:
    too_few = too_few_ratings(kept)
    notes += [f"Not computed for {r.system} in {r.task} · {r.control_class}: only {r.n} kept "
              "rating (two or more needed)." for r in too_few.itertuples(index=False)]
    usable = kept[~kept.set_index([*CELL, "system"]).index.isin(
        too_few.set_index([*CELL, "system"]).index)]
    if usable.empty:
        raise AnalysisInputError("no system has two or more kept ratings in any cell")
    pairs = signed_rank_pairs(usable, alpha=alpha, continuity=continuity_correction)
    untested = pairs[pairs["method"] == "not computed"] if len(pairs) else pairs
    notes += [f"No Wilcoxon test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: "
              "no page rated them differently." for r in untested.itertuples(index=False)]
    comparable, _ = comparable_cells(usable)
    left_out = sorted(set(map(tuple, usable[list(CELL)].drop_duplicates().to_numpy()))
                      - set(map(tuple, comparable[list(CELL)].drop_duplicates().to_numpy())))
    notes += [f"No mixed model for {task} · {cc}: fewer than two systems, or no rating "
              "variation within any system." for task, cc in left_out]
    mixed = mixed_model_means(comparable) if len(comparable) else pd.DataFrame()
    return {
        "system_medians_means": ("Median and mean rating per system with 95 % intervals",
                                 median_and_mean(usable)),
        "wilcoxon_pairs": ("Wilcoxon signed-rank tests on per-page differences, Holm corrected", pairs),
        "mixed_model_means": ("Linear mixed model (participant random intercept)", mixed),
    }


def _pairwise_tables(kept: pd.DataFrame, alpha: float, notes: list[str], reference: str | None) -> dict:
    pairs = preference_pairs(kept, alpha=alpha)
    if pairs.empty:
        raise AnalysisInputError("no page compares two analysed systems; nothing to analyse")
    undecided = pairs[pairs["wins_a"] + pairs["wins_b"] == 0]
    notes += [f"No sign test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: "
              "every page was answered 'no preference'." for r in undecided.itertuples(index=False)]
    pages = preference_pages(kept)
    scale, scale_notes = bradley_terry_scale(pages, reference=reference)
    notes += scale_notes
    return {
        "preference_pairs": ("Preference shares (Wilson 95 % intervals) and sign tests, Holm "
                             "corrected; 'no preference' left out of share and test", pairs),
        "bradley_terry": ("Bradley-Terry strengths (log-odds, centred) with 95 % intervals, and "
                          "each against the reference with its standard error", scale),
        "bradley_terry_covariance": ("Covariance of the centred Bradley-Terry strengths",
                                     bradley_terry_covariance(pages)),
        "side_bias": ("Share of preferences for the left clip", side_bias(kept)),
    }


def _appropriateness_tables(kept: pd.DataFrame, alpha: float, notes: list[str]) -> dict:
    shares = matched_preference(kept, alpha=alpha)
    pairs = score_pairs(kept, alpha=alpha)
    untested = pairs[pairs["method"] == "not computed"]
    notes += [f"No Wilcoxon test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: no "
              "participant who saw both scored them differently." for r in untested.itertuples(index=False)]
    return {
        "matched_preference": ("Share of pages preferring the matched clip ('no preference' split), Wilson "
                               "95 % intervals, sign tests of 50 %, Holm corrected over systems", shares),
        "appropriateness_scores": ("Mean appropriateness score (-2..+2) with 95 % bootstrap intervals over "
                                   "participants", appropriateness_scores(kept)),
        "score_pairs": ("Wilcoxon signed-rank tests of participants' mean scores between systems, Holm "
                        "corrected", pairs),
        "side_bias": ("Share of preferences for the left clip", side_bias(kept)),
    }


def _p_text(p: float) -> str:
    return "p < .001" if p < 0.001 else f"p = {p:.3f}".replace("0.", ".", 1)


def _exclusion_sentence(report: DesignReport, row) -> str:
    rules = report.rules
    removed = report.removed[report.removed["task"] == row.task]
    reasons = ", ".join(f"{r.participants} {r.reason}" for r in removed.itertuples(index=False))
    if report.design in PREFERENCE_DESIGNS:
        rule = attention_rule_text(rules, report.design)
        # both rows of a pairwise page share its flags, so pages are rows / 2
        collected, by_participant, early, kept = (
            n // 2 for n in (row.ratings_collected, row.discarded_participant,
                             row.discarded_early, row.ratings_kept))
        counted = f"{collected} pages were answered"
    else:
        in_task = report.flagged[report.flagged["task"] == row.task].iloc[0]
        lo, hi = int(in_task["scale_min"]), int(in_task["scale_max"])
        rule = attention_rule_text(rules, SIDE_BY_SIDE, (lo, hi))
        collected, by_participant, early, kept = (
            row.ratings_collected, row.discarded_participant, row.discarded_early, row.ratings_kept)
        pages = report.flagged[report.flagged["task"] == row.task].groupby(list(PAGE)).ngroups
        counted = f"{collected} ratings on {pages} pages were collected"
    return (f"**{row.task}.** Of {row.participants_total} participants, {row.participants_removed} "
            f"were removed for failing attention checks{f' ({reasons})' if reasons else ''}; "
            f"{rule}. {counted}; {by_participant} were discarded with the removed participants "
            f"and {early} because an answer came before a clip had finished playing, leaving "
            f"{kept}.")


def _in_cell(table: pd.DataFrame, task: str, cc: str) -> pd.DataFrame:
    return table[(table["task"] == task) & (table["control_class"] == cc)] if len(table) else table


def _interval(value: float, low: float, high: float, decimals: int) -> str:
    bounds = "n < 6" if pd.isna(low) else f"{low:.{decimals}f}, {high:.{decimals}f}"
    return f"{value:.{decimals}f} [{bounds}]"


def _side_by_side_sentence(report: DesignReport, task: str, cc: str) -> str:
    scores = _in_cell(report.table("system_medians_means"), task, cc).sort_values(
        ["median", "mean"], ascending=False)
    text = (f" In {cc}, the median ratings [95 % CI] were "
            + ", ".join(f"{r.system} {_interval(r.median, r.median_ci_low, r.median_ci_high, 0)}"
                        for r in scores.itertuples(index=False))
            + " and the means "
            + ", ".join(f"{r.system} {_interval(r.mean, r.ci_low, r.ci_high, 1)}"
                        for r in scores.itertuples(index=False)) + ".")
    pairs = _in_cell(report.table("wilcoxon_pairs"), task, cc)
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


def _pairwise_sentence(report: DesignReport, task: str, cc: str) -> str:
    pairs = _in_cell(report.table("preference_pairs"), task, cc)
    pairs = pairs[pairs["p"].notna()]
    if pairs.empty:
        return ""
    ties = int(pairs["no_preference"].sum())
    found = []
    for r in pairs[pairs["reject"]].itertuples(index=False):
        share, low, high = ((r.share_a, r.share_ci_low, r.share_ci_high) if r.preferred == r.system_a
                            else (1 - r.share_a, 1 - r.share_ci_high, 1 - r.share_ci_low))
        other = r.system_b if r.preferred == r.system_a else r.system_a
        found.append(f"{r.preferred} over {other} ({share * 100:.0f} % of preferences, 95 % CI "
                     f"{low * 100:.0f}-{high * 100:.0f} %, Holm-adjusted {_p_text(r.p_holm)})")
    scale = _in_cell(report.table("bradley_terry"), task, cc).sort_values("strength", ascending=False)
    text = (f" In {cc}, {int(pairs['n_pages'].sum())} pages compared {len(pairs)} pairs; "
            f"{ties} were answered 'no preference' and left out of the preference shares, the "
            f"exact two-sided binomial (sign) tests and the Bradley-Terry scale. With "
            f"Holm-Bonferroni correction over the pairs (family-wise α = {report.alpha:g}), "
            f"{len(found)} preference(s) were significant")
    text += f": {'; '.join(found)}." if found else "."
    if len(scale):
        text += (" On the Bradley-Terry scale (log-odds, centred, [95 % CI]): "
                 + ", ".join(f"{r.system} {_interval(r.strength, r.ci_low, r.ci_high, 2)}"
                             for r in scale.itertuples(index=False)) + ".")
    return text


def _appropriateness_sentence(report: DesignReport, task: str, cc: str) -> str:
    shares = _in_cell(report.table("matched_preference"), task, cc).set_index("system")
    scores = _in_cell(report.table("appropriateness_scores"), task, cc).sort_values("mean_score", ascending=False)
    each = [f"{r.system} {_interval(r.mean_score, r.ci_low, r.ci_high, 2)}, matched preferred on "
            f"{shares.at[r.system, 'share_matched'] * 100:.0f} % of {shares.at[r.system, 'n_pages']} pages "
            f"(95 % CI {shares.at[r.system, 'ci_low'] * 100:.0f}-{shares.at[r.system, 'ci_high'] * 100:.0f} %, "
            f"sign test {_p_text(shares.at[r.system, 'p_holm'])} Holm-adjusted)"
            for r in scores.itertuples(index=False)]
    text = (f" In {cc}, the mean appropriateness scores (-2 to +2, [95 % bootstrap CI over participants]) "
            f"were {'; '.join(each)}; 'no preference' counts half for each clip in the shares and is left "
            "out of the sign tests.")
    pairs = _in_cell(report.table("score_pairs"), task, cc)
    pairs = pairs[pairs["p"].notna()] if len(pairs) else pairs
    if len(pairs):
        found = [f"{r.higher} > {r.system_b if r.higher == r.system_a else r.system_a} ({_p_text(r.p_holm)})"
                 for r in pairs[pairs["reject"]].itertuples(index=False)]
        text += (f" Wilcoxon signed-rank tests of the participants' mean scores, Holm-Bonferroni corrected over "
                 f"the {len(pairs)} pairs (family-wise α = {report.alpha:g}), found "
                 + (f"{'; '.join(found)}." if found else "no significant difference."))
    return text


def design_summary_text(report: DesignReport) -> str:
    """Paragraphs a researcher can paste: exclusions and the tests' findings per task."""
    sentence, main = {SIDE_BY_SIDE: (_side_by_side_sentence, "system_medians_means"),
                      PAIRWISE: (_pairwise_sentence, "preference_pairs"),
                      APPROPRIATENESS: (_appropriateness_sentence, "matched_preference")}[report.design]
    cells = report.table(main)[list(CELL)].drop_duplicates().sort_values(list(CELL))
    out = []
    for row in report.exclusions.itertuples(index=False):
        text = _exclusion_sentence(report, row)
        for cc in cells.loc[cells["task"] == row.task, "control_class"]:
            text += sentence(report, row.task, cc)
        out.append(text)
    if report.leaderboard is not None:
        out.append(leaderboard_text(report.leaderboard))
    if report.rater_models is not None:
        out.append(rater_models_text(report.rater_models))
    if "power_more_ratings" in report.tables:
        out.append(power_summary(report.table("power_more_ratings"), report.alpha, POWER))
    return "\n\n".join(p for p in out if p) + "\n"


def design_figures(report: DesignReport) -> dict[str, Figure]:
    """The report's figures by file name: side by side, the median and mean per system (on
    the rating scale) and the significance matrix; pairwise, the preferences and the
    Bradley-Terry strengths; appropriateness, the matched share and the scores."""
    if report.design == SIDE_BY_SIDE:
        scores = report.table("system_medians_means")
        order = system_order(scores["system"].unique(), report.reference)
        figures = {"median_mean_ci": design_plots.scale_plot(
            scores, [("median", "median", "median_ci_low", "median_ci_high"), ("mean", "mean", "ci_low", "ci_high")],
            "rating (95 % interval)", order, plots.rating_scale(report.flagged))}
        if len(report.table("wilcoxon_pairs")):
            figures["significance_matrix"] = design_plots.significance_matrix_plot(report.table("wilcoxon_pairs"), scores)
        return figures
    if report.design == APPROPRIATENESS:
        scores = report.table("appropriateness_scores")
        order = system_order(scores["system"].unique(), report.reference)
        return design_plots.appropriateness_plots(report.table("matched_preference"), scores, order)
    figures = {"preferences": design_plots.preference_plot(report.table("preference_pairs"))}
    scale = report.table("bradley_terry")
    if len(scale):
        order = system_order(scale["system"].unique(), report.reference)
        figures["bradley_terry"] = design_plots.scale_plot(
            scale, [("strength", "strength", "ci_low", "ci_high")], "Bradley-Terry strength (log-odds, 95 % CI)", order)
    return figures


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
    for name, figure in design_figures(report).items():
        written += plots.save_figure(figure, figures, name)
    if report.leaderboard is not None:
        written += write_heat_maps(report.leaderboard, figures)
    notes = "".join(f"- {n}\n" for n in report.notes) or "- None: everything was computed.\n"
    summary = folder / "summary.md"
    summary.write_text("# Summary\n\n" + design_summary_text(report)
                       + "\n## Notes (what was not computed, and why)\n\n" + notes, encoding="utf-8")
    return [summary, *written]
