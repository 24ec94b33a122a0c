"""The researcher's list of a study's participants, and its CSV for approving or rejecting
submissions on the crowd platform.

One row per participant: their platform id and session, how far they got, how long it
took, their early answers (refused by the full-play rule or flagged), why they were
excluded and their questionnaire answers, with the action the study's rules suggest (approve the finished, reject those
who failed an attention check). Platform ids arrive in the entry link, so anyone can choose
one: every text cell is neutralised before a spreadsheet can read it as a formula.
"""

from __future__ import annotations

import csv
import io
from dataclasses import asdict, dataclass
from datetime import datetime

from django.db.models import Count, Q
from django.utils import timezone

from studyapp.models import Study
from studyapp.participants.assignment import is_idle
from studyapp.participants.views import SESSION_PARAMETERS

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


@dataclass(frozen=True)
class ParticipantRow:
    platform_id: str
    session: str  # Prolific's SESSION_ID, MTurk's assignmentId ("" for a plain link)
    status: str  # finished, in progress, idle (away longer than the reservation)
    started: datetime
    finished: datetime | None
    minutes_taken: float | None
    ratings: int
    early_answers: int
    exclusion_reason: str
    suggested_action: str  # approve, reject, or "" while unfinished (or screened out: they return it)
    answers: dict  # questionnaire answers by question name


def participant_rows(study: Study) -> list[ParticipantRow]:
    """Every participant of ``study`` in the order they started (one query)."""
    session = SESSION_PARAMETERS.get(study.platform, "")
    participants = study.participants.annotate(
        rating_count=Count("assignments__rating"),
        flagged=Count("assignments__rating", filter=Q(assignments__rating__answered_before_end=True)),
    ).order_by("started_at", "pk")
    now = timezone.now()
    rows = []
    for participant in participants:
        participant.study = study  # is_idle reads the reservation time
        finished = participant.finished_at
        if participant.screened_out_at is not None:
            status = "screened out"
        elif finished is not None:
            status = "finished"
        else:
            status = "idle" if is_idle(participant, now) else "in progress"
        action = "reject" if participant.excluded else "approve" if finished else ""
        rows.append(ParticipantRow(
            platform_id=participant.platform_id, session=participant.platform_data.get(session, "") if session else "",
            status=status, started=participant.started_at, finished=finished,
            minutes_taken=round((finished - participant.started_at).total_seconds() / 60, 1) if finished else None,
            ratings=participant.rating_count, early_answers=participant.refused_early + participant.flagged,
            exclusion_reason=participant.exclusion_reason, suggested_action=action, answers=participant.answers))
    return rows


def spreadsheet_safe(value: object) -> object:
    """``value``, with a text that a spreadsheet would run as a formula made plain text."""
    if isinstance(value, str) and value.startswith(FORMULA_STARTS):
        return "'" + value
    return value


def question_names(study: Study) -> list[str]:
    """The study's questions in the order participants meet them."""
    return list(study.questions.order_by("-part", "order", "created", "pk").values_list("name", flat=True))  # before, after


def participants_csv(study: Study) -> bytes:
    """The participant list as CSV, one ``answer_<name>`` column per question: times in
    ISO 8601, every text cell formula-safe."""
    names = question_names(study)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow([*(name for name in ParticipantRow.__dataclass_fields__ if name != "answers"),
                     *(f"answer_{name}" for name in names)])
    for row in participant_rows(study):
        cells = asdict(row)
        answers = cells.pop("answers")
        cells["started"] = row.started.isoformat()
        cells["finished"] = row.finished.isoformat() if row.finished else ""
        values = [*cells.values(), *(answers.get(name) for name in names)]
        writer.writerow(spreadsheet_safe("" if value is None else value) for value in values)
    return buffer.getvalue().encode()


__all__ = ["ParticipantRow", "participant_rows", "participants_csv", "question_names", "spreadsheet_safe"]
