"""The researcher's list of a study's participants, and its CSV for approving or rejecting
submissions on the crowd platform.

One row per participant: their platform id and session, how far they got (finished,
screened out, stopped by failed instructed checks, ...), how long it took, their early
answers (refused by the full-play rule or flagged), the instructed checks they failed,
whether their ratings are kept in the analysis and why not, and, apart from that, the
action the platform's rules suggest for their payment with its reason in words
(``platforms.rules``), what was last sent to the platform for them, and their
questionnaire answers. Platform ids arrive in the entry link, so anyone can choose one:
every text cell is neutralised before a spreadsheet can read it as a formula.
"""

from __future__ import annotations

import csv
import io
from dataclasses import asdict, dataclass
from datetime import datetime

from django.db.models import Count, Q
from django.utils import timezone

from studyapp.models import Participant, PlatformAction, Study, json_object
from studyapp.participants.assignment import is_idle
from studyapp.platforms.links import SESSION_PARAMETERS
from studyapp.platforms.rules import Standing, Submission, study_minutes, suggest

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


@dataclass(frozen=True)
class ParticipantRow:
    platform_id: str
    session: str  # Prolific's SESSION_ID, MTurk's assignmentId ("" for a plain link)
    status: str  # a rules.Standing: finished, screened out, stopped by checks, in progress, idle
    started: datetime
    finished: datetime | None
    minutes_taken: float | None
    ratings: int
    early_answers: int
    failed_checks: int  # instructed checks answered otherwise than the page asked
    excluded: bool  # their ratings are left out of the analysis
    exclusion_reason: str
    suggested_action: str  # for their payment: approve, reject, request return, or "" (nothing to do)
    action_reason: str  # why, in words
    sent_to_platform: str  # the last request sent for them that the platform took ("" if none)
    answers: dict  # questionnaire answers by question name


def standing(participant: Participant, now: datetime) -> Standing:
    """How far ``participant`` got (its ``study`` must be set: idleness reads the reservation time)."""
    if participant.screened_out_at is not None:
        return Standing.SCREENED_OUT
    if participant.stopped_at is not None:
        return Standing.STOPPED
    if participant.finished_at is not None:
        return Standing.FINISHED
    return Standing.IDLE if is_idle(participant, now) else Standing.IN_PROGRESS


def participant_rows(study: Study) -> list[ParticipantRow]:
    """Every participant of ``study`` in the order they started (two queries)."""
    session = SESSION_PARAMETERS.get(study.platform, "")
    participants = list(study.participants.annotate(
        rating_count=Count("assignments__rating"),
        flagged=Count("assignments__rating", filter=Q(assignments__rating__answered_before_end=True)),
    ).order_by("started_at", "pk"))
    sent = dict(PlatformAction.objects.filter(study=study, outcome=PlatformAction.Outcome.DONE,
                                              participant__isnull=False)
                .order_by("sent_at", "pk").values_list("participant_id", "action"))  # the latest wins
    now = timezone.now()
    for participant in participants:
        participant.study = study
        participant.standing = standing(participant, now)
    minutes = study_minutes([_minutes(p) for p in participants if p.standing == Standing.FINISHED])
    rows = []
    for participant in participants:
        suggestion = suggest(study, Submission(participant.standing, participant.failed_checks,
                                               participant.exclusion_reason if participant.excluded else ""), minutes)
        finished = participant.finished_at
        rows.append(ParticipantRow(
            platform_id=participant.platform_id,
            session=json_object(participant, "platform_data").get(session, "") if session else "",
            status=str(participant.standing), started=participant.started_at, finished=finished,
            minutes_taken=round(_minutes(participant), 1) if finished else None,
            ratings=participant.rating_count, early_answers=participant.refused_early + participant.flagged,
            failed_checks=participant.failed_checks, excluded=participant.excluded,
            exclusion_reason=participant.exclusion_reason, suggested_action=suggestion.action,
            action_reason=suggestion.reason, sent_to_platform=sent.get(participant.pk, ""),
            answers=json_object(participant, "answers")))
    return rows


def _minutes(participant: Participant) -> float:
    return (participant.finished_at - participant.started_at).total_seconds() / 60


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


__all__ = ["ParticipantRow", "participant_rows", "participants_csv", "question_names", "spreadsheet_safe", "standing"]
