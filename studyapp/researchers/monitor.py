"""What the researcher watches while a study runs: participants, ratings, means with CIs.

Everything is computed from the exported ratings table (the CSV a researcher
downloads), read back through ``analysis.ratings`` and flagged by
``analysis.exclusions`` with the study's own thresholds, so the page agrees with the
analysis report. Means and 95 % confidence intervals are over kept ratings (excluded
participants and early answers left out, as the papers report them).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import pandas as pd
from django.db.models import Q
from django.utils.safestring import SafeString

from analysis.exclusions import ExclusionRules, apply_exclusions
from analysis.pairwise import preference_pairs
from analysis.power import more_ratings_for_power
from analysis.ratings import read_ratings
from analysis.side_by_side import median_and_mean
from analysis.stats import system_means
from analysis.tables import spreadsheet_safe
from studyapp.designs.ratings import export_columns, ratings_rows
from studyapp.models import ATTENTION_NAME, NATURAL_NAME, Stimulus, Study
from studyapp.researchers.reports import html_table


def ratings_csv(study: Study, for_spreadsheets: bool = False) -> bytes:
    """The study's ratings table (docs/ratings-schema.md) as CSV.

    ``for_spreadsheets``: text a spreadsheet would run as a formula (a system named
    ``=HYPERLINK(...)``) gets a leading apostrophe, for the file a researcher downloads.
    """
    rows = ratings_rows(study)
    if for_spreadsheets:
        rows = ({column: spreadsheet_safe(value) for column, value in row.items()} for row in rows)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=export_columns(study), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue().encode()


def exclusion_rules(study: Study) -> ExclusionRules:
    return ExclusionRules(natural_system=NATURAL_NAME, attention_system=ATTENTION_NAME,
                          bad_at_or_above=study.bad_threshold, natural_below=study.natural_threshold,
                          discard_early=study.discard_early)


def flagged_ratings(study: Study) -> pd.DataFrame:
    """The ratings table with ``kept``, ``excluded_participant`` and ``discarded_early`` flags (may be empty)."""
    csv_bytes = ratings_csv(study)
    if csv_bytes.count(b"\n") < 2:
        return pd.DataFrame(columns=[*export_columns(study), "kept"])
    return apply_exclusions(read_ratings(io.StringIO(csv_bytes.decode())), exclusion_rules(study))


@dataclass(frozen=True)
class SystemMean:
    system: str
    n: int  # kept ratings
    mean: float | None
    ci_low: float | None  # None with fewer than two ratings: no interval exists
    ci_high: float | None
    scale: tuple[int, int] | None = None  # the rating scale, which no shown interval leaves

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
    means_by_class: dict[str, list[SystemMean]]  # control class (held-out, synthetic, ...) -> the same per system


def system_mean_rows(kept: pd.DataFrame, systems: list[str], scale: tuple[int, int] | None = None) -> list[SystemMean]:
    """Mean ± 95 % CI of each system's kept ratings; systems with fewer than two get what exists."""
    counts = kept.groupby("system").size()
    rateable = [s for s in systems if counts.get(s, 0) >= 2]
    table = (system_means(kept[kept["system"].isin(rateable)], groupby=()).set_index("system")
             if rateable else pd.DataFrame())
    rows = []
    for system in systems:
        n = int(counts.get(system, 0))
        if system in rateable:
            row = table.loc[system]
            rows.append(SystemMean(system, n, float(row["mean"]), float(row["ci_low"]), float(row["ci_high"]), scale))
        else:
            values = kept.loc[kept["system"] == system, "value"]
            rows.append(SystemMean(system, n, float(values.mean()) if n else None, None, None, scale))
    return rows


def compared_ratings(study: Study, kept: pd.DataFrame) -> pd.DataFrame:
    """The kept ratings of the compared systems: BAD's rows left out, and on pairwise pages
    the whole page showing BAD (a BAD-versus-NAT check compares nothing)."""
    if study.design != Study.Design.PAIRWISE:
        return kept[kept["system"] != ATTENTION_NAME]
    checks = kept.loc[kept["system"] == ATTENTION_NAME, ["participant", "page"]].drop_duplicates()
    on_check = kept.merge(checks, on=["participant", "page"], how="left", indicator=True)["_merge"] == "both"
    return kept[~on_check.to_numpy()]


def analysis_tables(study: Study, kept: pd.DataFrame) -> list[tuple[str, SafeString]]:
    """What the analysis says so far: the design's summary (side-by-side: medians and means;
    pairwise: preference shares) and, for every design, the ratings needed for 80 % power."""
    compared = compared_ratings(study, kept)
    counts = compared.groupby("system").size()
    compared = compared[compared["system"].isin(counts.index[counts >= 2])]
    if compared["system"].nunique() < 2:
        return []
    tables = []
    if study.design == Study.Design.SIDE_BY_SIDE:
        tables.append(("Median and mean per system (95 % CIs)", median_and_mean(compared)))
    elif study.design == Study.Design.PAIRWISE:
        tables.append(("Preference per pair (Wilson 95 % CI, sign test, Holm)", preference_pairs(compared)))
    tables.append(("How many more ratings give 80 % power per pair (at alpha 0.05)", more_ratings_for_power(compared)))
    return [(title, html_table(table)) for title, table in tables]


def study_monitor(study: Study) -> StudyMonitor:
    participants = study.participants.all()
    flagged = flagged_ratings(study)
    kept = flagged[flagged["kept"].astype(bool)]
    done = list(study.stimuli.filter(status=Stimulus.Status.DONE).values_list("token", flat=True))
    collected = flagged.groupby("stimulus").size().reindex(done, fill_value=0)
    kept_counts = kept.groupby("stimulus").size().reindex(done, fill_value=0)
    systems = sorted({s.export_name for s in study.systems.all()})
    scale = (study.scale_min, study.scale_max)
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
        # Pairwise pages carry preferences, not values: their summary is the analysis report's.
        means=system_mean_rows(kept, systems, scale) if study.design != Study.Design.PAIRWISE else [],
        means_by_class={name: system_mean_rows(group, systems, scale)
                        for name, group in kept.groupby("control_class", sort=True)}
        if study.design != Study.Design.PAIRWISE else {},
        failed_instructed_checks=participants.filter(failed_checks__gt=0).count(),
        tables=analysis_tables(study, kept),
    )


__all__ = ["StudyMonitor", "SystemMean", "flagged_ratings", "ratings_csv", "study_monitor"]
