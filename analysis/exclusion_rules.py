"""Exclusion rules of MoGlow Sec. 5.2, applied as flags and reported as the paper does.

Rules (MoGlow defaults on a 1-5 scale):

1. A participant who rates any attention-check clip (system BAD) at 4 or above, or any
   natural clip (system NAT) below 2, is excluded: all their ratings, in every task.
2. A rating given before its clip finished playing is discarded.

Other scales: a threshold t on the 1-5 reference scale maps linearly onto
``[scale_min, scale_max]`` as ``scale_min + (t - 1) * (scale_max - scale_min) / 4``, and
integer ratings are compared with that real-valued threshold without rounding. On 1-10,
BAD >= 7.75 means BAD >= 8 and NAT < 3.25 means NAT <= 3.

Each rating design applies the rules to its table and states them in words
(`analysis.designs`): pairwise designs have no ratings to threshold, so there rule 1
reads "prefers the attention-check clip" and rule 2 discards a whole page.

Nothing is deleted. Each rating gets ``excluded_participant``, ``discarded_early``,
``kept`` and ``exclusion_reason``; a rating that breaks both rules is counted under the
participant exclusion, so ratings collected = discarded by each reason + kept.

Each rule is written once, as a method of `ExclusionRules` that takes a whole table's
columns or one answer's values alike: the study app flags a participant with the same
methods as their answers arrive, and writes the rules it applied as JSON
(``ExclusionRules.to_json``), which ``python -m analysis report --rules`` reads back. The
functions below apply them to a table whose design object is handed in
(`analysis.ratings.exclusions` finds it from the table); the object answers what differs
between designs (`RuledDesign`), so this module sits below the designs.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, fields
from typing import Protocol

import pandas as pd

from analysis.errors import AnalysisInputError

REFERENCE_SCALE = (1, 5)


class RuledDesign(Protocol):
    """What the rules ask of a table's design (`analysis.designs.base.RatingDesign`)."""

    def attention_failures(self, df: pd.DataFrame, rules: ExclusionRules) -> list[tuple[pd.Series, str]]: ...

    def early_answers(self, ratings: pd.DataFrame) -> pd.Series: ...

    def compared(self, kept: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame: ...

    def ruled_systems(self, rules: ExclusionRules) -> tuple[str, ...]: ...


@dataclass(frozen=True)
class ExclusionRules:
    """Thresholds are given on the 1-5 reference scale and rescaled per rating."""

    natural_system: str = "NAT"
    attention_system: str = "BAD"
    bad_at_or_above: float = 4.0
    natural_below: float = 2.0
    discard_early: bool = True
    attention_rule: bool = True  # off when the attention-check system is compared as a system

    def __post_init__(self) -> None:
        # NaN compares false with every rating, which would silently exclude nobody.
        for name in ("bad_at_or_above", "natural_below"):
            if not math.isfinite(getattr(self, name)):
                raise AnalysisInputError(f"the exclusion threshold {name} must be a finite number, "
                                         f"got {getattr(self, name)}")

    # The rules themselves. Each takes a table's columns (Series) or one answer's values.

    def rated_attention_high(self, system, value, scale_min, scale_max):
        """Rule 1: an attention-check clip rated at or above the (rescaled) BAD threshold."""
        return self.attention_rule & (system == self.attention_system) & (
            value >= scaled_threshold(self.bad_at_or_above, scale_min, scale_max))

    def rated_natural_low(self, system, value, scale_min, scale_max):
        """Rule 1: a natural clip rated below the (rescaled) NAT threshold."""
        return (system == self.natural_system) & (
            value < scaled_threshold(self.natural_below, scale_min, scale_max))

    def preferred_attention(self, system, answer, side):
        """Rule 1 on pairwise pages: the attention-check clip is the one preferred."""
        return self.attention_rule & (system == self.attention_system) & (answer == side)

    def preferred_mismatched_attention(self, system, answer, side, matched):
        """Rule 1 on appropriateness pages: on a check page (both clips the attention-check
        system's), the clip made for another control is the one preferred."""
        return self.preferred_attention(system, answer, side) & ~matched

    @property
    def attention_reason(self) -> str:
        return f"rated a {self.attention_system} clip high"

    @property
    def natural_reason(self) -> str:
        return f"rated a {self.natural_system} clip low"

    @property
    def preference_reason(self) -> str:
        return f"preferred a {self.attention_system} clip"

    @property
    def mismatch_reason(self) -> str:
        return f"preferred the mismatched clip of a {self.attention_system} page"

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2) + "\n"

    @classmethod
    def from_json(cls, text: str, source: str = "the rules") -> ExclusionRules:
        """Rules written by ``to_json`` (the study app's rules.json); AnalysisInputError
        naming ``source`` and the field for anything else."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise AnalysisInputError(f"{source} is not JSON: {exc}") from None
        if not isinstance(data, dict):
            raise AnalysisInputError(f"{source} must be a JSON object of exclusion rules")
        known = {f.name: f for f in fields(cls)}
        if unknown := sorted(set(data) - set(known)):
            raise AnalysisInputError(f"{source}: unknown field(s) {', '.join(unknown)}; the rules are "
                                     f"{', '.join(known)}")
        for name, value in data.items():
            expected = {"str": str, "float": (int, float), "bool": bool}[known[name].type]
            if not isinstance(value, expected) or (known[name].type == "float" and isinstance(value, bool)):
                raise AnalysisInputError(f"{source}: {name} must be a {known[name].type}, not {value!r}")
        try:
            return cls(**data)
        except AnalysisInputError as exc:
            raise AnalysisInputError(f"{source}: {exc}") from None


def scaled_threshold(threshold: float, scale_min: int | pd.Series, scale_max: int | pd.Series):
    """Map a threshold on the 1-5 reference scale onto another rating scale."""
    lo, hi = REFERENCE_SCALE
    return scale_min + (threshold - lo) * (scale_max - scale_min) / (hi - lo)


def apply_exclusions(ratings: pd.DataFrame, rules: ExclusionRules, design: RuledDesign) -> pd.DataFrame:
    """Return a copy of a validated ratings table with the exclusion flags added.

    ``exclusion_reason`` is one of ``""`` (kept), ``"rated a BAD clip high"``,
    ``"rated a NAT clip low"`` and ``"answered before clip end"`` (with the configured
    system names); a participant who failed both attention rules is attributed to the
    BAD rule. Pairwise tables get the preference rule instead (reason ``"preferred a
    BAD clip"``), appropriateness tables theirs (``"preferred the mismatched clip of a
    BAD page"``).
    """
    df = ratings.copy()
    reason = pd.Series("", index=df.index, dtype=object)
    failed = design.attention_failures(df, rules)
    for failing, why in reversed(failed):  # the first rule a participant failed names their reason
        reason[df["participant"].isin(set(df.loc[failing, "participant"]))] = why
    df["excluded_participant"] = reason != ""
    df["discarded_early"] = early_discards(df, rules, df["excluded_participant"], design)
    df["kept"] = ~(df["excluded_participant"] | df["discarded_early"])
    reason[df["discarded_early"]] = "answered before clip end"
    df["exclusion_reason"] = reason
    return df


def early_discards(ratings: pd.DataFrame, rules: ExclusionRules, excluded: pd.Series,
                   design: RuledDesign) -> pd.Series:
    """Rule 2 for a table: the ratings discarded for an answer before a clip's end (not
    counted again where ``excluded`` already removes them). On a pairwise page the one
    answer covers both clips, so an early answer discards the page."""
    if not rules.discard_early or "answered_before_end" not in ratings.columns:
        return pd.Series(False, index=ratings.index)
    return design.early_answers(ratings) & ~excluded


def compared_ratings(flagged: pd.DataFrame, rules: ExclusionRules, design: RuledDesign) -> pd.DataFrame:
    """The kept ratings that enter the comparisons: without the attention-check system's
    ratings unless it is compared (``rules.attention_rule`` off). A pairwise or
    appropriateness page showing it goes whole: without its attention clip a page
    compares nothing."""
    kept = flagged[flagged["kept"].astype(bool)]
    return design.compared(kept, rules) if rules.attention_rule else kept


def exclusion_notes(flagged: pd.DataFrame, rules: ExclusionRules, design: RuledDesign) -> list[str]:
    """Plain-language notes on rules that could not be applied or that disagree with the app."""
    notes = []
    if rules.discard_early and "answered_before_end" not in flagged.columns:
        notes.append(
            "The early-answer rule was not applied: the table has neither "
            "answered_before_end, played_until_s + clip_duration_s, nor shown_at + "
            "answered_at + clip_duration_s."
        )
    if "app_excluded_participant" in flagged.columns:
        differ = int((flagged["app_excluded_participant"] != flagged["excluded_participant"]).sum())
        if differ:
            notes.append(
                f"The web app's excluded_participant flag disagrees with the recomputed rule "
                f"on {differ} rating(s); the recomputed flags were used."
            )
    if "app_discarded_early" in flagged.columns:
        # compared among participants still in, since apps differ in whether they also
        # flag the early answers of excluded participants
        inside = ~flagged["excluded_participant"]
        differ = int((flagged["app_discarded_early"] != flagged["discarded_early"])[inside].sum())
        if differ:
            notes.append(
                f"The web app's discarded_early flag disagrees with the recomputed rule on "
                f"{differ} rating(s); the recomputed flags were used."
            )
    for system in design.ruled_systems(rules):
        if not (flagged["system"] == system).any():
            notes.append(f"No ratings of {system} clips: its attention rule excluded nobody.")
    return notes


def exclusion_summary(flagged: pd.DataFrame) -> pd.DataFrame:
    """One row per task in the words of MoGlow Sec. 5.2.

    Columns: task, participants_total, participants_removed, ratings_collected,
    discarded_participant, discarded_early, ratings_kept, ratings_per_stimulus_min,
    ratings_per_stimulus_max (kept ratings per stimulus, over stimuli of that task).
    """
    rows = []
    for task, group in flagged.groupby("task", sort=True):
        per_participant = group.groupby("participant")["excluded_participant"].any()
        kept_per_stimulus = group[group["kept"]].groupby("stimulus").size().reindex(
            group["stimulus"].unique(), fill_value=0
        )
        rows.append({
            "task": task,
            "participants_total": int(len(per_participant)),
            "participants_removed": int(per_participant.sum()),
            "ratings_collected": int(len(group)),
            "discarded_participant": int(group["excluded_participant"].sum()),
            "discarded_early": int(group["discarded_early"].sum()),
            "ratings_kept": int(group["kept"].sum()),
            "ratings_per_stimulus_min": int(kept_per_stimulus.min()),
            "ratings_per_stimulus_max": int(kept_per_stimulus.max()),
        })
    return pd.DataFrame(rows)


def removed_by_reason(flagged: pd.DataFrame) -> pd.DataFrame:
    """Participants removed per task and rule: columns task, reason, participants."""
    removed = flagged[flagged["excluded_participant"]]
    counts = removed.groupby(["task", "exclusion_reason"])["participant"].nunique()
    return counts.rename("participants").reset_index().rename(columns={"exclusion_reason": "reason"})
