"""The study's ratings table (docs/reference/ratings-schema.md) and the rules it was collected under.

One row per rating, with the columns every design shares and, in front, the page
structure its design adds (``Design.export_columns``); designs whose answers are not on
a scale (pairwise) carry no value or scale columns. A clip is named twice: ``stimulus``
is the opaque token its video is served under, ``clip`` its motion files' name in the
study's motion export (``stimuli.motion_export.clip_name``; empty for an uploaded video),
by which ``python -m analysis report --motion`` matches each rated clip to its metrics.
The table is the researcher's (behind login and the owner check); no participant page
shows either name beside a system. A study whose pages ask for reasons adds GENEA's
columns ``juiceOptions`` and ``juiceOtherReason`` (``analysis.reports.reasons``).
Instructed checks are left out: their answers were dictated, not given. Each row carries the live flags: the participant's
exclusion as it was set when their answers arrived, and the early-answer discard, the
analysis's own rule (``analysis.ratings.exclusions.early_discards``) with the study's rules.

``rules_json`` is those rules as ``python -m analysis report --rules`` reads them.
"""

from __future__ import annotations

import csv
import io

import pandas as pd

from analysis.ratings.exclusions import early_discards
from analysis.reports.reasons import OTHER, REASON_COLUMNS, options_text
from analysis.reports.tables import spreadsheet_safe
from studyapp.designs.design import Design
from studyapp.designs.registry import design_of
from studyapp.designs.rules import StudyRules
from studyapp.models import Rating, Study
from studyapp.stimuli.motion_export import clip_name

EXPORT_COLUMNS = (
    "participant", "system", "stimulus", "clip", "task", "control_class", "value", "scale_min", "scale_max",
    "clip_duration_s", "shown_at", "answered_at", "client_started_s", "client_ended_s", "client_answered_s",
    "played_until_s", "answered_before_end",
    "excluded_participant", "discarded_early", "exclusion_reason",
)
SCALE_COLUMNS = ("value", "scale_min", "scale_max")


def design_export_columns(design: Design) -> tuple[str, ...]:
    """The columns of a ratings table of ``design`` (each declared in ``analysis.ratings.schema.COLUMNS``)."""
    shared = EXPORT_COLUMNS if design.on_scale else tuple(c for c in EXPORT_COLUMNS if c not in SCALE_COLUMNS)
    return (*design.export_columns, *shared)


def export_columns(study: Study) -> tuple[str, ...]:
    """The columns of the study's ratings table, by its design (and GENEA's reason columns
    where its pages ask for reasons)."""
    return design_export_columns(design_of(study)) + (REASON_COLUMNS if study.reason_list else ())


def reason_fields(rating: Rating) -> dict[str, str]:
    """A rating's reasons in GENEA's columns: the options ticked ("Other" among them where
    the participant wrote something) and the words under "Other"."""
    ticked = [*rating.reasons, *([OTHER] if rating.other_reason else [])]
    return dict(zip(REASON_COLUMNS, (options_text(ticked), rating.other_reason)))


def ratings_rows(study: Study) -> list[dict]:
    """The study's ratings in the schema of docs/reference/ratings-schema.md, one dict per rating."""
    design = design_of(study)
    ratings = (Rating.objects.filter(assignment__participant__study=study, assignment__expected="")
               .select_related("assignment__participant", "assignment__stimulus__system",
                               "assignment__stimulus__control", "assignment__stimulus__shown_control")
               .order_by("answered_at", "pk"))
    columns = export_columns(study)
    rows = []
    for rating in ratings:
        assignment = rating.assignment
        participant, stimulus = assignment.participant, assignment.stimulus
        row = {
            "participant": participant.code,
            "system": stimulus.system.export_name,
            "stimulus": stimulus.token,
            "clip": clip_name(stimulus) if stimulus.control_id is not None else "",
            "task": "all",
            "control_class": stimulus.control_class,
            "value": rating.value,
            "scale_min": study.scale_min,
            "scale_max": study.scale_max,
            "clip_duration_s": stimulus.duration_s,
            "shown_at": assignment.shown_at.isoformat() if assignment.shown_at else "",
            "answered_at": rating.answered_at.isoformat(),
            "client_started_s": rating.client_started_s,
            "client_ended_s": rating.client_ended_s,
            "client_answered_s": rating.client_answered_s,
            "played_until_s": rating.played_until_s,
            "answered_before_end": rating.answered_before_end,
            "excluded_participant": participant.excluded,
            "exclusion_reason": participant.exclusion_reason,
            **design.export_fields(assignment, rating),
            **reason_fields(rating),
        }
        rows.append({column: row.get(column) for column in columns})
    if rows:
        table = pd.DataFrame(rows)
        discarded = early_discards(table, StudyRules.of(study).exclusion, table["excluded_participant"])
        for row, early in zip(rows, discarded.tolist()):
            row["discarded_early"] = early
            row["exclusion_reason"] = row["exclusion_reason"] or ("answered before clip end" if early else "")
    return rows


def ratings_csv(study: Study, for_spreadsheets: bool = False) -> bytes:
    """The study's ratings table as CSV.

    ``for_spreadsheets``: text a spreadsheet would run as a formula (a system named
    ``=HYPERLINK(...)``) gets a leading apostrophe, for the file a researcher downloads.
    """
    rows = ratings_rows(study)
    if for_spreadsheets:
        rows = [{column: spreadsheet_safe(value) for column, value in row.items()} for row in rows]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=export_columns(study), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue().encode()


def rules_json(study: Study) -> str:
    """The study's exclusion rules as ``python -m analysis report --rules`` reads them."""
    return StudyRules.of(study).exclusion.to_json()
