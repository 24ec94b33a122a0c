"""The single design: one clip per page, rated on the scale (MoGlow, HVRNN).

Its table is the minimal schema and its rules are the rated clips' defaults of
`RatingDesign`. Its report is `analysis.reports.single_report`'s: the MoGlow Table 2 layout, the
one-way ANOVA and Tukey HSD per cell, the mixed models, and the objective metrics when
motion is given, which no other design's report takes.
"""

from __future__ import annotations

import pandas as pd

from analysis.designs.base import RatingDesign
from analysis.exclusion_rules import ExclusionRules
from analysis.motion.motion_io import SystemClips
from analysis.reports.single_report import Report, build_single_report


class Single(RatingDesign):
    name = "single"
    takes_motion = True
    planned_tests = (
        "per task and control class, each system's mean rating with its 95 % confidence interval (MoGlow Table 2)",
        "a one-way ANOVA of the ratings between systems, and Tukey's HSD on every pair of systems",
        "a linear mixed model of the ratings with a random intercept per participant",
        "the rater- and clip-aware models: a crossed linear mixed model, a cumulative link mixed model and "
        "Krippendorff's alpha",
        "the ratings needed for 80 % power per pair of systems",
    )

    def schema_title(self) -> str:
        return "the minimal schema"

    def build_report(self, ratings: pd.DataFrame, rules: ExclusionRules, reference: str | None,
                     continuity_correction: bool, motion: dict[str, SystemClips] | None,
                     foot_joints: list[str] | None, foot_kind: str) -> Report:
        return build_single_report(ratings, self, rules, reference, motion, foot_joints, foot_kind)
