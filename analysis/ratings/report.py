"""The whole report of a ratings table: `build_report` finds the table's design
(`analysis.designs.design_of`), which builds its report (`analysis.reports.single_report`
for the single design, `analysis.reports.design_report` for the others); `write_report`
and `summary_text` (`analysis.reports.single_report`) take either.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import pandas as pd

from analysis.designs import design_of
from analysis.errors import AnalysisInputError
from analysis.exclusion_rules import ExclusionRules
from analysis.motion.motion_io import SystemClips
from analysis.reports.design_report import DesignReport
from analysis.reports.single_report import Report


def require_design_taking_motion(ratings: pd.DataFrame) -> None:
    """Objective metrics join a report of single-design ratings only; motion rated in
    other designs is measured by ``python -m analysis objective``."""
    if not design_of(ratings).takes_motion:
        raise AnalysisInputError(
            "objective metrics (--motion) are reported with single-design ratings; run "
            "'python -m analysis objective' on the motion alone")


def build_report(ratings: pd.DataFrame, motion: dict[str, SystemClips] | None = None,
                 reference: str | None = None, rules: ExclusionRules = ExclusionRules(),
                 systems: Sequence[str] | None = None, compare_attention_checks: bool = False,
                 foot_joints: Sequence[str] | None = None,
                 foot_kind: str = "heel", continuity_correction: bool = False) -> Report | DesignReport:
    """Run the whole analysis on a validated ratings table (see `analysis.ratings.schema`).

    The table's design builds the report (`analysis.designs`): a single-design table gets a
    `Report` (`build_single_report`), side-by-side, pairwise and appropriateness tables a
    `DesignReport` (`analysis.reports.design_report`); `write_report` and `summary_text` take either.

    ``reference`` marks significance in Table 2 (default NAT when rated). ``systems``,
    when given, lists the systems expected; any other system in the ratings is an error.
    ``continuity_correction`` applies to the side-by-side and appropriateness Wilcoxon tests' normal
    approximation. BAD clips are attention checks, left out of the comparisons unless
    ``compare_attention_checks``, which compares BAD as a system and excludes nobody on it.
    """
    rated = set(ratings["system"].unique())
    if systems is not None:
        unknown = rated - set(systems) - {rules.attention_system}
        if unknown:
            raise AnalysisInputError(
                f"unknown system(s) in the ratings: {', '.join(sorted(unknown))}; expected "
                f"{', '.join(systems)}")
    if motion:
        require_design_taking_motion(ratings)
    if compare_attention_checks:
        rules = replace(rules, attention_rule=False)
    return design_of(ratings).build_report(ratings, rules, reference, continuity_correction, motion,
                                           foot_joints, foot_kind)
