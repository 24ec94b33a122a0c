"""The appropriateness design: a pairwise page whose two clips come from the same system,
one made for the control the page shows and one for another; which fits the shown control
better? (GENEA's appropriateness question, five levels.)

Its table is the pairwise one plus ``matched`` (true on the clip made for the shown
control) on each row, both rows naming the same system, ``strength`` 1 (slightly) or 2
(clearly). Its pages follow the pairwise rules but for the attention check: a page is one
when its system is BAD (natural motion against a path it obviously does not follow), and
preferring the mismatched clip on one excludes.

Its report (`analysis.stats.matching`): per system the share of pages preferring the
matched clip (ties split, Wilson interval) with a sign test of 50 %, the mean
appropriateness score with a bootstrap interval over participants, Wilcoxon tests of
every pair of systems' scores, Holm corrected, and the raters' side bias. No power
table: its systems are not compared on shared pages.
"""

from __future__ import annotations


import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import design_plots
from analysis.stats.matching import appropriateness_scores, matched_preference, score_pairs
from analysis.reports.design_report import DesignReport, in_cell, interval_text, p_text
from analysis.pages import PAGE, every_page, first_row
from analysis.designs.pairwise import Pairwise
from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import ExclusionRules
from analysis.stats.preferences import side_bias
from analysis.reports.tables import system_order


class Appropriateness(Pairwise):
    name = "appropriateness"
    votes = False
    judges_appropriateness = True
    boolean_columns = ("matched",)

    def required_columns(self, minimal: tuple[str, ...]) -> tuple[str, ...]:
        return (*super().required_columns(minimal), "matched")

    def check_page_systems(self, df: pd.DataFrame) -> pd.DataFrame:
        """A page shows one system's clip for the shown control and its clip for another
        (``matched`` already read as booleans)."""
        pages = df.groupby(list(PAGE), sort=False)
        every_page(df, pages["system"].transform("nunique") == 1,
                   "an appropriateness page shows one system twice, its matched and its mismatched clip",
                   otherwise="shows two systems")
        every_page(df, pages["matched"].transform("sum") == 1,
                   "an appropriateness page has one matched clip (matched true) and one mismatched (false)")
        if "strength" in df.columns:
            strong = df["strength"].notna() & (df["strength"] > 2)
            if strong.any():
                raise AnalysisInputError(
                    "an appropriateness answer has five levels, a preference of strength 1 (slightly) or 2 "
                    f"(clearly); row {first_row(strong)} gives strength {int(df.loc[strong, 'strength'].iloc[0])}")
        return df

    def attention_failures(self, df: pd.DataFrame, rules: ExclusionRules) -> list[tuple[pd.Series, str]]:
        return [(rules.preferred_mismatched_attention(df["system"], df["answer"], df["side"], df["matched"]),
                 rules.mismatch_reason)]

    def attention_check_failed(self, rules: ExclusionRules) -> str:
        return f"preferred the mismatched clip of any {rules.attention_system} page"

    def power_pairs(self, frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
        raise AnalysisInputError("appropriateness pages compare no two systems: no power per pair of systems")

    planned_tests = (
        "per system, the share of pages preferring the matched clip (ties split, Wilson interval) with a sign "
        "test of 50 %",
        "per system, the mean appropriateness score with a bootstrap interval over participants",
        "Wilcoxon tests of every pair of systems' scores, Holm corrected, and the raters' side bias",
    )
    effect_words = "none: appropriateness pages compare no two systems, so its plan counts the targets' participants"

    def planned_units(self, effect: float, systems: int, alpha: float, power: float) -> int:
        raise ValueError("appropriateness pages compare no two systems: no power per pair of systems plans its "
                         "participants; leave the expected effect empty")

    # The report.

    main_table = "matched_preference"

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None:
        shares = matched_preference(kept, alpha=report.alpha)
        pairs = score_pairs(kept, alpha=report.alpha, continuity=report.continuity_correction)
        untested = pairs[pairs["method"] == "not computed"]
        report.notes += [f"No Wilcoxon test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: no "
                         "participant who saw both scored them differently." for r in untested.itertuples(index=False)]
        scores = appropriateness_scores(kept)
        report.notes += [f"Appropriateness score of {r.system} in {r.task} · {r.control_class}: {r.warning}."
                         for r in scores.itertuples(index=False) if r.warning]
        report.tables.update({
            "matched_preference": ("Share of pages preferring the matched clip ('no preference' split), Wilson "
                                   "95 % intervals, sign tests of 50 %, Holm corrected over systems", shares),
            "appropriateness_scores": ("Mean appropriateness score (-2..+2) with 95 % bootstrap intervals over "
                                       "participants", scores),
            "score_pairs": ("Wilcoxon signed-rank tests of participants' mean scores between systems, Holm "
                            "corrected", pairs),
            "side_bias": ("Share of preferences for the left clip", side_bias(kept)),
        })

    def cell_sentence(self, report: DesignReport, task: str, cc: str) -> str:
        shares = in_cell(report.table("matched_preference"), task, cc).set_index("system")
        scores = in_cell(report.table("appropriateness_scores"), task, cc).sort_values("mean_score", ascending=False)
        each = [f"{r.system} {interval_text(r.mean_score, r.ci_low, r.ci_high, 2, 'too few ratings')}, "
                f"matched preferred on "
                f"{shares.at[r.system, 'share_matched'] * 100:.0f} % of {shares.at[r.system, 'n_pages']} pages "
                f"(95 % CI {shares.at[r.system, 'ci_low'] * 100:.0f}-{shares.at[r.system, 'ci_high'] * 100:.0f} %, "
                f"sign test {p_text(shares.at[r.system, 'p_holm'])} Holm-adjusted)"
                for r in scores.itertuples(index=False)]
        text = (f" In {cc}, the mean appropriateness scores (-2 to +2, [95 % bootstrap CI over participants]) "
                f"were {'; '.join(each)}; 'no preference' counts half for each clip in the shares and is left "
                "out of the sign tests.")
        pairs = in_cell(report.table("score_pairs"), task, cc)
        pairs = pairs[pairs["p"].notna()] if len(pairs) else pairs
        if len(pairs):
            found = [f"{r.higher} > {r.system_b if r.higher == r.system_a else r.system_a} ({p_text(r.p_holm)})"
                     for r in pairs[pairs["reject"]].itertuples(index=False)]
            correction = "with" if report.continuity_correction else "without"
            text += (f" Two-sided Wilcoxon signed-rank tests of the participants' mean scores (exact up to 50 "
                     f"participants without tied differences, else the normal approximation {correction} continuity "
                     f"correction), Holm-Bonferroni corrected over the {len(pairs)} pairs (family-wise "
                     f"α = {report.alpha:g}), found "
                     + (f"{'; '.join(found)}." if found else "no significant difference."))
        return text

    def figures(self, report: DesignReport) -> dict[str, Figure]:
        """The share preferring the matched clip and the mean score per system."""
        scores = report.table("appropriateness_scores")
        order = system_order(scores["system"].unique(), report.reference)
        return design_plots.appropriateness_plots(report.table("matched_preference"), scores, order)
