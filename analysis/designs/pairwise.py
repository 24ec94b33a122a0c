"""The pairwise design: one page shows two systems' clips and asks which is better.

Its table has two rows per page, one per clip, with its ``side`` and the page's ``answer``
(and optionally its ``strength``) on both, and no values or scales. A page is answered
by a preference, so the rules read: a participant who prefers the attention-check clip on
any page that shows one (a BAD versus NAT page in the studies this project runs) is
excluded, "no preference" there does not exclude; an answer before either clip finished
playing discards the page, both its rows; a page showing the attention-check system is
left out of the comparisons whole, since without it the page compares nothing.

Its report: per pair the preference share with its Wilson interval and the share of "no
preference", exact two-sided binomial (sign) tests on the pages with a preference,
Holm-Bonferroni corrected, a Bradley-Terry scale with 95 % intervals, a check of the
raters' side bias, the leaderboard (`analysis.reports.leaderboard_report`: graded votes
weighted, Elo with bootstrap intervals, win-fraction and battle heat maps) and the pages
needed for 80 % power per pair.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import design_plots
from analysis.rankings.bradley_terry import bradley_terry_covariance, bradley_terry_scale
from analysis.reports.design_report import DesignReport, exclusion_sentence, in_cell, interval_text, p_text, power_table
from analysis.designs.base import RatingDesign
from analysis.pages import (ANSWERS, NO_PREFERENCE, PAGE, SIDES, every_page, first_row, labels,
                                    no_system_twice_on_a_page, positive_integers)
from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import ExclusionRules
from analysis.reports.leaderboard_report import build_leaderboard, leaderboard_tables, write_heat_maps
from analysis.stats.preferences import preference_pages, preference_pairs, side_bias
from analysis.stats.power import pages_for_preference, pairs_of, pairwise_pairs
from analysis.reports.tables import system_order

_SCALE_COLUMNS = ("value", "scale_min", "scale_max")


class Pairwise(RatingDesign):
    name = "pairwise"
    rated = False
    votes = True

    def required_columns(self, minimal: tuple[str, ...]) -> tuple[str, ...]:
        return (*(c for c in minimal if c not in _SCALE_COLUMNS), "page", "side", "answer")

    def check_pages(self, df: pd.DataFrame) -> pd.DataFrame:
        """Returns the table with ``side`` and ``answer`` lower-cased and ``strength`` as
        integers (nullable)."""
        df = df.copy()
        df["page"] = labels(df["page"], "page")
        for column, allowed in (("side", SIDES), ("answer", ANSWERS)):
            df[column] = df[column].astype(str).str.strip().str.lower()
            bad = ~df[column].isin(allowed)
            if bad.any():
                raise AnalysisInputError(
                    f"column {column!r} must be one of {', '.join(allowed)}; row {first_row(bad)} "
                    f"holds {df.loc[bad, column].iloc[0]!r}")
        if "strength" in df.columns:
            df["strength"] = positive_integers(df["strength"], "strength", allow_empty=True)
            undecided = df["strength"].notna() & (df["answer"] == NO_PREFERENCE)
            if undecided.any():
                raise AnalysisInputError(
                    f"'strength' qualifies a preference, but row {first_row(undecided)} gives one "
                    f"with answer {NO_PREFERENCE!r}")
        pages = df.groupby(list(PAGE), sort=False)
        every_page(df, (pages["side"].transform("size") == 2) & (pages["side"].transform("nunique") == 2),
                   "a pairwise page must have exactly two rows, one on each side")
        every_page(df, pages["answer"].transform("nunique") == 1,
                   "the two rows of a pairwise page must carry the same answer")
        return self.check_page_systems(df)

    def check_page_systems(self, df: pd.DataFrame) -> pd.DataFrame:
        """The systems a page shows (its two rows already checked)."""
        no_system_twice_on_a_page(df)
        return df

    # The rules applied to a table.

    def attention_failures(self, df: pd.DataFrame, rules: ExclusionRules) -> list[tuple[pd.Series, str]]:
        return [(rules.preferred_attention(df["system"], df["answer"], df["side"]), rules.preference_reason)]

    def early_answers(self, ratings: pd.DataFrame) -> pd.Series:
        # the one answer covers both clips, so an early answer discards the page
        early = ratings["answered_before_end"].astype(bool)
        return early.groupby([ratings[column] for column in PAGE], sort=False).transform("any")

    def compared(self, kept: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
        shows_check = kept["system"] == rules.attention_system
        check_pages = kept.loc[shows_check, list(PAGE)].set_index(list(PAGE)).index
        return kept[~(shows_check | kept.set_index(list(PAGE)).index.isin(check_pages))]

    def ruled_systems(self, rules: ExclusionRules) -> tuple[str, ...]:
        return (rules.attention_system,) if rules.attention_rule else ()

    # The rules in words.

    def rule_text(self, rules: ExclusionRules, scale: tuple[int, int] | None = None) -> str:
        if not rules.attention_rule:
            return f"no attention check was applied ({rules.attention_system} was compared as a system)"
        return f"a participant was removed who {self.attention_check_failed(rules)}"

    def attention_check_failed(self, rules: ExclusionRules) -> str:
        """What a participant removed by the attention rule did."""
        return f"preferred a {rules.attention_system} clip on any page showing one"

    def early_rule_text(self, rules: ExclusionRules) -> str:
        return ("A page answered before its clips had finished playing is discarded whole."
                if rules.discard_early else "Pages answered before their clips had finished playing are kept.")

    def described(self, rules: ExclusionRules) -> list[str]:
        rule, early = super().described(rules)
        # the study's rating thresholds are set whatever its design: say that they do not apply here
        thresholds = (f"The rating thresholds ({rules.attention_system} {rules.bad_at_or_above:g} or higher, "
                      f"{rules.natural_system} below {rules.natural_below:g}, on a 1-5 scale) do not apply: "
                      f"{self.name} pages are answered by a preference, not rated.")
        return [rule, thresholds, early]

    def power_pairs(self, frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
        return pairwise_pairs(frame, alpha, power)

    planned_tests = (
        "per pair of systems, the share of pages preferring each with its Wilson interval, and the share of "
        "no preference",
        "exact two-sided binomial (sign) tests on the pages with a preference, Holm-Bonferroni corrected",
        "a Bradley-Terry scale with 95 % intervals, and a check of the raters' side bias",
        "the leaderboard: graded votes weighted, Elo with bootstrap intervals",
        "the pages needed for 80 % power per pair of systems",
    )
    effect_words = "the share of pages preferring the better of two systems (above 0.5, at most 1)"
    planned_unit = "pages with a preference"
    units_per_pair = True

    def planned_units(self, effect: float, systems: int, alpha: float, power: float) -> int:
        return pages_for_preference(effect, pairs_of(systems), alpha, power)

    # The report.

    main_table = "preference_pairs"

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None:
        pairs = preference_pairs(kept, alpha=report.alpha)
        if pairs.empty:
            raise AnalysisInputError("no page compares two analysed systems; nothing to analyse")
        undecided = pairs[pairs["wins_a"] + pairs["wins_b"] == 0]
        report.notes += [f"No sign test of {r.system_a} and {r.system_b} in {r.task} · {r.control_class}: "
                         "every page was answered 'no preference'." for r in undecided.itertuples(index=False)]
        pages = preference_pages(kept)
        scale, scale_notes = bradley_terry_scale(pages, reference=report.reference)
        report.notes += scale_notes
        report.tables.update({
            "preference_pairs": ("Preference shares (Wilson 95 % intervals) and sign tests, Holm "
                                 "corrected; 'no preference' left out of share and test", pairs),
            "bradley_terry": ("Bradley-Terry strengths (log-odds, centred) with 95 % intervals, and "
                              "each against the reference with its standard error", scale),
            "bradley_terry_covariance": ("Covariance of the centred Bradley-Terry strengths",
                                         bradley_terry_covariance(pages)),
            "side_bias": ("Share of preferences for the left clip", side_bias(kept)),
        })
        anchor = report.reference if report.reference in set(kept["system"]) else None
        report.leaderboard = build_leaderboard(kept, anchor, natural=report.rules.natural_system)
        report.tables.update(leaderboard_tables(report.leaderboard))
        report.notes += report.leaderboard.notes
        report.tables["power_more_ratings"] = power_table(kept, self, report.alpha)

    def exclusion_sentence(self, report: DesignReport, row) -> str:
        # both rows of a page share its flags, so pages are rows / 2
        collected, discarded, early, kept = (n // 2 for n in (row.ratings_collected, row.discarded_participant,
                                                              row.discarded_early, row.ratings_kept))
        return exclusion_sentence(report, row, self.rule_text(report.rules), f"{collected} pages were answered",
                                  discarded, early, kept)

    def cell_sentence(self, report: DesignReport, task: str, cc: str) -> str:
        pairs = in_cell(report.table("preference_pairs"), task, cc)
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
                         f"{low * 100:.0f}-{high * 100:.0f} %, Holm-adjusted {p_text(r.p_holm)})")
        scale = in_cell(report.table("bradley_terry"), task, cc).sort_values("strength", ascending=False)
        text = (f" In {cc}, {int(pairs['n_pages'].sum())} pages compared {len(pairs)} pairs; "
                f"{ties} were answered 'no preference' and left out of the preference shares, the "
                f"exact two-sided binomial (sign) tests and the Bradley-Terry scale. With "
                f"Holm-Bonferroni correction over the pairs (family-wise α = {report.alpha:g}), "
                f"{len(found)} preference(s) were significant")
        text += f": {'; '.join(found)}." if found else "."
        if len(scale):
            text += (" On the Bradley-Terry scale (log-odds, centred, [95 % CI]): "
                     + ", ".join(f"{r.system} {interval_text(r.strength, r.ci_low, r.ci_high, 2)}"
                                 for r in scale.itertuples(index=False)) + ".")
        return text

    def figures(self, report: DesignReport) -> dict[str, Figure]:
        """The preference per pair and the Bradley-Terry strengths."""
        figures = {"preferences": design_plots.preference_plot(report.table("preference_pairs"))}
        scale = report.table("bradley_terry")
        if len(scale):
            order = system_order(scale["system"].unique(), report.reference)
            figures["bradley_terry"] = design_plots.scale_plot(
                scale, [("strength", "strength", "ci_low", "ci_high")], "Bradley-Terry strength (log-odds, 95 % CI)",
                order)
        return figures

    def write_figures(self, report: DesignReport, folder: Path) -> list[Path]:
        """The figures, and the leaderboard's heat maps beside them (where there is a leaderboard)."""
        heat_maps = write_heat_maps(report.leaderboard, folder) if report.leaderboard is not None else []
        return super().write_figures(report, folder) + heat_maps
