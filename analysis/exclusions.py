"""Exclusion rules of MoGlow Sec. 5.2, applied as flags and reported as the paper does.

Rules (MoGlow defaults on a 1-5 scale):

1. A participant who rates any attention-check clip (system BAD) at 4 or above, or any
   natural clip (system NAT) below 2, is excluded: all their ratings, in every task.
2. A rating given before its clip finished playing is discarded.

Other scales: a threshold t on the 1-5 reference scale maps linearly onto
``[scale_min, scale_max]`` as ``scale_min + (t - 1) * (scale_max - scale_min) / 4``, and
integer ratings are compared with that real-valued threshold without rounding. On 1-10,
BAD >= 7.75 means BAD >= 8 and NAT < 3.25 means NAT <= 3.

Pairwise designs (`analysis.designs`) have no ratings to threshold. There rule 1 reads:
a participant who prefers the attention-check clip on any page that shows one (a BAD
versus NAT page in the studies this project runs) is excluded; "no preference" there
does not exclude. Rule 2 discards a page, both its rows, when either clip was answered
before it finished playing.

When the attention-check system is itself compared (``--compare-attention-checks``),
``attention_rule`` is off: its ratings exclude nobody, and the summaries say which rule
was applied (`attention_rule_text`).

Nothing is deleted. Each rating gets ``excluded_participant``, ``discarded_early``,
``kept`` and ``exclusion_reason``; a rating that breaks both rules is counted under the
participant exclusion, so ratings collected = discarded by each reason + kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from analysis.designs import PAGE, PAIRWISE, table_design
from analysis.errors import AnalysisInputError

REFERENCE_SCALE = (1, 5)


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


def scaled_threshold(threshold: float, scale_min: int | pd.Series, scale_max: int | pd.Series):
    """Map a threshold on the 1-5 reference scale onto another rating scale."""
    lo, hi = REFERENCE_SCALE
    return scale_min + (threshold - lo) * (scale_max - scale_min) / (hi - lo)


def apply_exclusions(ratings: pd.DataFrame, rules: ExclusionRules = ExclusionRules()) -> pd.DataFrame:
    """Return a copy of a validated ratings table with the exclusion flags added.

    ``exclusion_reason`` is one of ``""`` (kept), ``"rated a BAD clip high"``,
    ``"rated a NAT clip low"`` and ``"answered before clip end"`` (with the configured
    system names); a participant who failed both attention rules is attributed to the
    BAD rule. Pairwise tables get the preference rule instead (reason ``"preferred a
    BAD clip"``).
    """
    if table_design(ratings) == PAIRWISE:
        return _apply_preference_exclusions(ratings, rules)
    df = ratings.copy()
    failed_bad = rules.attention_rule & (df["system"] == rules.attention_system) & (
        df["value"] >= scaled_threshold(rules.bad_at_or_above, df["scale_min"], df["scale_max"])
    )
    failed_nat = (df["system"] == rules.natural_system) & (
        df["value"] < scaled_threshold(rules.natural_below, df["scale_min"], df["scale_max"])
    )
    bad_participants = set(df.loc[failed_bad, "participant"])
    nat_participants = set(df.loc[failed_nat, "participant"]) - bad_participants
    by_bad = df["participant"].isin(bad_participants)
    by_nat = df["participant"].isin(nat_participants)
    df["excluded_participant"] = by_bad | by_nat
    if rules.discard_early and "answered_before_end" in df.columns:
        df["discarded_early"] = df["answered_before_end"] & ~df["excluded_participant"]
    else:
        df["discarded_early"] = False
    df["kept"] = ~(df["excluded_participant"] | df["discarded_early"])
    reason = pd.Series("", index=df.index, dtype=object)
    reason[by_bad] = f"rated a {rules.attention_system} clip high"
    reason[by_nat] = f"rated a {rules.natural_system} clip low"
    reason[df["discarded_early"]] = "answered before clip end"
    df["exclusion_reason"] = reason
    return df


def _apply_preference_exclusions(ratings: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
    df = ratings.copy()
    preferred_bad = rules.attention_rule & (df["system"] == rules.attention_system) & (df["answer"] == df["side"])
    df["excluded_participant"] = df["participant"].isin(set(df.loc[preferred_bad, "participant"]))
    if rules.discard_early and "answered_before_end" in df.columns:
        early_page = df.groupby(list(PAGE), sort=False)["answered_before_end"].transform("any")
        df["discarded_early"] = early_page & ~df["excluded_participant"]
    else:
        df["discarded_early"] = False
    df["kept"] = ~(df["excluded_participant"] | df["discarded_early"])
    reason = pd.Series("", index=df.index, dtype=object)
    reason[df["excluded_participant"]] = f"preferred a {rules.attention_system} clip"
    reason[df["discarded_early"]] = "answered before clip end"
    df["exclusion_reason"] = reason
    return df


def exclusion_notes(flagged: pd.DataFrame, rules: ExclusionRules = ExclusionRules()) -> list[str]:
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
    ruled = (() if table_design(flagged) == PAIRWISE else (rules.natural_system,))
    for system in ((rules.attention_system,) if rules.attention_rule else ()) + ruled:
        if not (flagged["system"] == system).any():
            notes.append(f"No ratings of {system} clips: its attention rule excluded nobody.")
    return notes


def attention_rule_text(rules: ExclusionRules, design: str,
                        scale: tuple[int, int] | None = None) -> str:
    """The attention rules applied, as a report states them ("a participant was removed
    who ..."), on ``scale`` (default: the 1-5 reference scale, rescaled for others)."""
    checked = rules.attention_system
    if design == PAIRWISE:
        if not rules.attention_rule:
            return f"no attention check was applied ({checked} was compared as a system)"
        return f"a participant was removed who preferred a {checked} clip on any page showing one"
    lo, hi = scale or REFERENCE_SCALE
    where = f"on the {lo}-{hi} scale" if scale else "on a 1-5 scale; scaled linearly on others"
    natural = f"any {rules.natural_system} clip below {scaled_threshold(rules.natural_below, lo, hi):g}"
    if not rules.attention_rule:
        return (f"a participant was removed who rated {natural} ({where}); {checked} was compared "
                "as a system, not used as an attention check")
    return (f"a participant was removed who rated any {checked} clip "
            f"{scaled_threshold(rules.bad_at_or_above, lo, hi):g} or higher or {natural} ({where})")


def compared_ratings(flagged: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
    """The kept ratings that enter the comparisons: without the attention-check system's
    ratings unless it is compared (``rules.attention_rule`` off). A pairwise page showing
    it goes whole: without its attention clip a pair compares nothing."""
    kept = flagged[flagged["kept"]]
    if not rules.attention_rule:
        return kept
    drop = kept["system"] == rules.attention_system
    if table_design(kept) == PAIRWISE:
        check_pages = kept.loc[drop, list(PAGE)].set_index(list(PAGE)).index
        drop |= kept.set_index(list(PAGE)).index.isin(check_pages)
    return kept[~drop]


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
