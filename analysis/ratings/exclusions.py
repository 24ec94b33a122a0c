"""The exclusion rules applied to a ratings table as it comes: each function finds the
table's design (`analysis.designs.design_of`) and hands it to the rules' steps in
`analysis.exclusion_rules`, where the rules, their defaults and the flags are described.

The rules themselves (`ExclusionRules`, `scaled_threshold`) and the tables of what was
removed (`exclusion_summary`, `removed_by_reason`) need no design; they are importable
from here too, so that one module holds everything a user of the exclusions calls.
"""

from __future__ import annotations

import pandas as pd

from analysis import exclusion_rules
from analysis.designs import design_of
from analysis.exclusion_rules import (REFERENCE_SCALE, ExclusionRules, exclusion_summary, removed_by_reason,
                                      scaled_threshold)

__all__ = ["REFERENCE_SCALE", "ExclusionRules", "apply_exclusions", "compared_ratings", "early_discards",
           "exclusion_notes", "exclusion_summary", "removed_by_reason", "scaled_threshold"]


def apply_exclusions(ratings: pd.DataFrame, rules: ExclusionRules = ExclusionRules()) -> pd.DataFrame:
    """A copy of a validated ratings table with the exclusion flags added
    (`analysis.exclusion_rules.apply_exclusions`)."""
    return exclusion_rules.apply_exclusions(ratings, rules, design_of(ratings))


def early_discards(ratings: pd.DataFrame, rules: ExclusionRules, excluded: pd.Series) -> pd.Series:
    """The ratings rule 2 discards (`analysis.exclusion_rules.early_discards`)."""
    return exclusion_rules.early_discards(ratings, rules, excluded, design_of(ratings))


def compared_ratings(flagged: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
    """The kept ratings that enter the comparisons (`analysis.exclusion_rules.compared_ratings`)."""
    return exclusion_rules.compared_ratings(flagged, rules, design_of(flagged))


def exclusion_notes(flagged: pd.DataFrame, rules: ExclusionRules = ExclusionRules()) -> list[str]:
    """Notes on rules that could not be applied or that disagree with the app
    (`analysis.exclusion_rules.exclusion_notes`)."""
    return exclusion_rules.exclusion_notes(flagged, rules, design_of(flagged))
