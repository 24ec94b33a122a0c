"""What the researcher watches while a study runs: participants, ratings, means with CIs.

Everything is computed from the exported ratings table (the CSV a researcher
downloads), read back through ``analysis.ratings.schema`` and flagged by
``analysis.ratings.exclusions`` with the study's own rules (``designs.rules``), so the page
agrees with the analysis report. Means and 95 % confidence intervals are over kept
ratings (excluded participants and early answers left out, as the papers report them),
where the design's answers are on a scale; the design adds its own summary
(``Design.monitor_tables``).
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import pandas as pd
from django.db.models import Q
from django.utils.safestring import SafeString

from analysis.ratings.exclusions import apply_exclusions, compared_ratings
from analysis.stats.minimums import INTERVAL_FEW_PARTICIPANTS, few_participants_warning
from analysis.ratings.more_ratings import more_ratings_for_power
from analysis.reports.rater_models import build_rater_models
from analysis.ratings.schema import read_ratings
from analysis.stats.anova import system_means
from studyapp.designs.registry import design_of
from studyapp.designs.rules import StudyRules
from studyapp.models import Stimulus, Study
from studyapp.researchers.results.export import export_columns, ratings_csv
from studyapp.researchers.results.reports import html_table


def flagged_ratings(study: Study) -> pd.DataFrame:
    """The ratings table with ``kept``, ``excluded_participant`` and ``discarded_early`` flags (may be empty)."""
    csv_bytes = ratings_csv(study)
    if csv_bytes.count(b"\n") < 2:
        return pd.DataFrame(columns=[*export_columns(study), "kept"])
    return apply_exclusions(read_ratings(io.StringIO(csv_bytes.decode())), StudyRules.of(study).exclusion)


@dataclass(frozen=True)
class SystemMean:
    system: str
    n: int  # kept ratings
    mean: float | None
    ci_low: float | None  # None with fewer than two ratings: no interval exists
    ci_high: float | None
    scale: tuple[int, int] | None = None  # the rating scale, which no shown interval leaves
    participants: int = 0  # who gave the kept ratings

    @property
    def warning(self) -> str:
        """What makes the interval less certain than it looks (few participants), or ""."""
        return "" if self.ci_low is None else few_participants_warning(self.participants)

    @property
    def ci_half(self) -> float | None:
        return None if self.ci_low is None else (self.ci_high - self.ci_low) / 2

    @property
    def shown_low(self) -> float | None:
        """The interval's low end within the scale: no mean can lie below its lowest point."""
        return None if self.ci_low is None or self.scale is None else max(self.ci_low, self.scale[0])

    @property
    def shown_high(self) -> float | None:
        return None if self.ci_high is None or self.scale is None else min(self.ci_high, self.scale[1])


@dataclass(frozen=True)
class StudyMonitor:
    participants_started: int
    participants_finished: int
    participants_excluded: int  # failed an attention check
    participants_early: int  # answered a clip before its end at least once (refused or flagged)
    ratings_collected: int
    ratings_kept: int
    clips: int  # finished stimuli
    per_stimulus_min: int  # ratings collected per finished stimulus
    per_stimulus_max: int
    kept_per_stimulus_min: int
    kept_per_stimulus_max: int
    means: list[SystemMean]
    failed_instructed_checks: int  # participants who failed at least one
    tables: list[tuple[str, SafeString]]  # the design's own summary and the power table, by the analysis
    analysis_notes: list[str]  # what the models of the tables say of their fits
    means_by_class: dict[str, list[SystemMean]]  # control class (held-out, synthetic, ...) -> the same per system

    few_participants = INTERVAL_FEW_PARTICIPANTS  # intervals from fewer participants carry a warning

    @property
    def means_warned(self) -> bool:
        """Whether an interval of the means tables carries a warning (the page explains the mark)."""
        return any(row.warning for rows in [self.means, *self.means_by_class.values()] for row in rows)


def system_mean_rows(kept: pd.DataFrame, systems: list[str], scale: tuple[int, int] | None = None) -> list[SystemMean]:
    """Mean ± 95 % CI of each system's kept ratings; systems with fewer than two get what exists.
    An interval from fewer than ``INTERVAL_FEW_PARTICIPANTS`` participants carries a warning."""
    counts = kept.groupby("system").size()
    participants = kept.groupby("system")["participant"].nunique()
    rateable = [s for s in systems if counts.get(s, 0) >= 2]
    table = (system_means(kept[kept["system"].isin(rateable)], groupby=()).set_index("system")
             if rateable else pd.DataFrame())
    rows = []
    for system in systems:
        n, raters = int(counts.get(system, 0)), int(participants.get(system, 0))
        if system in rateable:
            row = table.loc[system]
            rows.append(SystemMean(system, n, float(row["mean"]), float(row["ci_low"]), float(row["ci_high"]), scale,
                                   raters))
        else:
            values = kept.loc[kept["system"] == system, "value"]
            rows.append(SystemMean(system, n, float(values.mean()) if n else None, None, None, scale, raters))
    return rows


def analysis_tables(study: Study, kept: pd.DataFrame) -> tuple[list[tuple[str, SafeString]], list[str]]:
    """What the analysis says so far: the design's summary, for rated clips the crossed
    linear mixed model, the cumulative link mixed model and Krippendorff's alpha, and, for
    every design, the ratings needed for 80 % power (once two systems have two compared
    ratings each); and the models' notes (a boundary fit, a model that could not be fitted)."""
    compared = compared_ratings(kept, StudyRules.of(study).exclusion) if len(kept) else kept
    counts = compared.groupby("system").size()
    compared = compared[compared["system"].isin(counts.index[counts >= 2])]
    if compared["system"].nunique() < 2:
        return [], []
    design = design_of(study)
    tables, notes = list(design.monitor_tables(compared)), []
    if design.on_scale:  # rated clips (single, side by side): the rater- and clip-aware models, as the report's
        natural = StudyRules.of(study).exclusion.natural_system
        models = build_rater_models(compared, natural if natural in set(compared["system"]) else None)
        tables += [(title, table) for title, table in models.tables().values() if len(table)]
        notes = models.notes
    if design.power_table:
        tables.append(("How many more ratings give 80 % power per pair (at alpha 0.05)",
                       more_ratings_for_power(compared)))
    return [(title, html_table(table)) for title, table in tables], notes


def study_monitor(study: Study) -> StudyMonitor:
    participants = study.participants.all()
    flagged = flagged_ratings(study)
    kept = flagged[flagged["kept"].astype(bool)]
    done = list(study.stimuli.filter(status=Stimulus.Status.DONE).values_list("token", flat=True))
    collected = flagged.groupby("stimulus").size().reindex(done, fill_value=0)
    kept_counts = kept.groupby("stimulus").size().reindex(done, fill_value=0)
    tables, notes = analysis_tables(study, kept)
    systems = sorted({s.export_name for s in study.systems.all()})
    scale = (study.scale_min, study.scale_max)
    on_scale = design_of(study).on_scale
    return StudyMonitor(
        participants_started=participants.count(),
        participants_finished=participants.filter(finished_at__isnull=False).count(),
        participants_excluded=participants.filter(excluded=True).count(),
        participants_early=participants.filter(
            Q(refused_early__gt=0) | Q(assignments__rating__answered_before_end=True)).distinct().count(),
        ratings_collected=len(flagged),
        ratings_kept=len(kept),
        clips=len(done),
        per_stimulus_min=int(collected.min()) if done else 0,
        per_stimulus_max=int(collected.max()) if done else 0,
        kept_per_stimulus_min=int(kept_counts.min()) if done else 0,
        kept_per_stimulus_max=int(kept_counts.max()) if done else 0,
        # Preferences (pairwise) have no means: their summary is the design's table.
        means=system_mean_rows(kept, systems, scale) if on_scale else [],
        means_by_class={name: system_mean_rows(group, systems, scale)
                        for name, group in kept.groupby("control_class", sort=True)} if on_scale else {},
        failed_instructed_checks=participants.filter(failed_checks__gt=0).count(),
        tables=tables,
        analysis_notes=notes,
    )


__all__ = ["StudyMonitor", "SystemMean", "flagged_ratings", "study_monitor"]
