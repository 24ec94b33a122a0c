"""What a rating design answers for the analysis: the interface of `analysis.designs`' objects.

A design object says everything that differs between designs in the analysis:

- the table: the columns it needs beyond the minimal schema, and the page structure it
  checks (`analysis.ratings.schema` calls both);
- the rules (`analysis.ratings.exclusions`): which rows fail the attention rule, which answers
  came before their clips had played, and which kept ratings are compared;
- the words: its rules as the report and the study app state them;
- the report: which report it gets (`analysis.reports.single_report` for the single design,
  `analysis.reports.design_report` for the designs of several clips on a page), and there its
  tables, figures and summary sentences, and the power calculation of its test.

The defaults here are those of the designs whose clips are each rated on a scale (single,
side by side); the preference designs (pairwise, appropriateness) override them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd
from matplotlib.figure import Figure

from analysis.reports import plots
from analysis.reports.design_report import DesignReport, build_design_report
from analysis.exclusion_rules import REFERENCE_SCALE, ExclusionRules, scaled_threshold
from analysis.stats.power import pairs_of, ratings_per_system_for_effect, single_pairs

if TYPE_CHECKING:
    from analysis.motion.motion_io import SystemClips
    from analysis.reports.single_report import Report


class RatingDesign:
    """One rating design as the analysis treats it; the registry (`analysis.designs`) makes
    one object per design and hands it out for each table of that design."""

    name: str  # as the ratings table's ``design`` column says it
    rated = True  # each row is one clip's value on a scale (else one preference answers a page)
    votes = False  # each page is a vote between two systems' clips, which a leaderboard ranks
    judges_appropriateness = False  # a page sets a system's clip for its control against one for another
    takes_motion = False  # objective metrics (``--motion``) join its report
    boolean_columns: tuple[str, ...] = ()  # read as true/false before the pages are checked

    def __repr__(self) -> str:
        return f"<rating design {self.name}>"

    # The table.

    def required_columns(self, minimal: tuple[str, ...]) -> tuple[str, ...]:
        """The columns a table of this design must have, given the single design's ``minimal``."""
        return minimal

    def schema_title(self) -> str:
        """How an error message names the schema of this design's tables."""
        return f"the minimal schema of a {self.name} table"

    def check_pages(self, df: pd.DataFrame) -> pd.DataFrame:
        """The table with its page columns checked and normalised (labels already checked)."""
        return df

    # The rules applied to a table (`analysis.ratings.exclusions`).

    def attention_failures(self, df: pd.DataFrame, rules: ExclusionRules) -> list[tuple[pd.Series, str]]:
        """(rows failing a rule, its reason) for each attention rule, the first rule a
        participant fails naming their reason."""
        scale = (df["value"], df["scale_min"], df["scale_max"])
        return [(rules.rated_attention_high(df["system"], *scale), rules.attention_reason),
                (rules.rated_natural_low(df["system"], *scale), rules.natural_reason)]

    def early_answers(self, ratings: pd.DataFrame) -> pd.Series:
        """The rows whose answer came before a clip could have finished playing."""
        return ratings["answered_before_end"].astype(bool)

    def compared(self, kept: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
        """The kept ratings that enter the comparisons while the attention rule holds."""
        return kept[kept["system"] != rules.attention_system]

    def ruled_systems(self, rules: ExclusionRules) -> tuple[str, ...]:
        """The systems whose clips an attention rule judges."""
        return (*((rules.attention_system,) if rules.attention_rule else ()), rules.natural_system)

    # The rules in words: one wording, which the report and the study app both use.

    def rule_text(self, rules: ExclusionRules, scale: tuple[int, int] | None = None) -> str:
        """The attention rules, as a report states them ("a participant was removed who ..."),
        on ``scale`` (default: the 1-5 reference scale, rescaled for others)."""
        lo, hi = scale or REFERENCE_SCALE
        where = f"on the {lo}-{hi} scale" if scale else "on a 1-5 scale; scaled linearly on others"
        natural = f"any {rules.natural_system} clip below {scaled_threshold(rules.natural_below, lo, hi):g}"
        if not rules.attention_rule:
            return (f"a participant was removed who rated {natural} ({where}); {rules.attention_system} was "
                    "compared as a system, not used as an attention check")
        return (f"a participant was removed who rated any {rules.attention_system} clip "
                f"{scaled_threshold(rules.bad_at_or_above, lo, hi):g} or higher or {natural} ({where})")

    def early_rule_text(self, rules: ExclusionRules) -> str:
        return ("A rating given before its clip had finished playing is discarded." if rules.discard_early
                else "Ratings given before their clip had finished playing are kept.")

    def described(self, rules: ExclusionRules) -> list[str]:
        """The rules as sentences, in the words of the report."""
        rule = self.rule_text(rules)
        return [f"{rule[0].upper()}{rule[1:]}.", self.early_rule_text(rules)]

    # The report.

    def build_report(self, ratings: pd.DataFrame, rules: ExclusionRules, reference: str | None,
                     continuity_correction: bool, motion: dict[str, SystemClips] | None,
                     foot_joints: list[str] | None, foot_kind: str) -> Report | DesignReport:
        """The report of a validated table of this design (`analysis.ratings.report.build_report`
        has checked the arguments and applied ``compare_attention_checks`` to ``rules``)."""
        return build_design_report(ratings, self, reference, rules, continuity_correction=continuity_correction)

    def power_pairs(self, frame: pd.DataFrame, alpha: float, power: float) -> pd.DataFrame:
        """The pairs of one cell with the ratings their test needs for ``power`` (`analysis.stats.power`)."""
        return single_pairs(frame, alpha, power)

    # The plan, before any rating exists (the study app locks it when a study opens).

    # The report's tests and models in words, the analysis a plan commits to; a design
    # that names none plans only its report's tables.
    planned_tests: tuple[str, ...] = ()
    effect_words = "a standardised difference of two systems' mean ratings (Cohen's d)"
    planned_unit = "ratings per system"  # what `planned_units` counts
    units_per_pair = False  # the units are counted per pair of systems (else per system)

    def planned_units(self, effect: float, systems: int, alpha: float, power: float) -> int:
        """The units (``planned_unit``) at which the design's test of a pair of ``systems``
        compared systems detects an ``effect`` (``effect_words``) at ``alpha``, split over
        the pairs, with ``power``; ValueError for an effect outside its range."""
        return ratings_per_system_for_effect(effect, pairs_of(systems), alpha, power)

    # The parts of a `DesignReport` (`analysis.reports.design_report`), for the designs that get one.

    main_table: str  # the table whose cells the summary walks

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None:
        """Add the design's tables (and notes, models) to ``report`` from the compared ``kept`` ratings."""
        raise NotImplementedError

    def exclusion_sentence(self, report: DesignReport, row) -> str:
        """The summary's sentence on one task's exclusions (``row`` of ``report.exclusions``)."""
        raise NotImplementedError

    def cell_sentence(self, report: DesignReport, task: str, control_class: str) -> str:
        """The summary's sentences on one cell's findings."""
        raise NotImplementedError

    def figures(self, report: DesignReport) -> dict[str, Figure]:
        """The report's figures by file name."""
        raise NotImplementedError

    def write_figures(self, report: DesignReport, folder: Path) -> list[Path]:
        """Write the figures into ``folder``; the files written."""
        written = []
        for name, figure in self.figures(report).items():
            written += plots.save_figure(figure, folder, name)
        return written
