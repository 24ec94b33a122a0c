"""Recording a participant's rating, flagging exclusions, and the ratings table.

The rules are MoGlow Sec. 5.2's, as ``analysis.exclusions`` applies them: a participant
who rates any BAD clip at or above the study's (rescaled) BAD threshold, or any NAT clip
below its NAT threshold, is excluded; a rating given before its clip finished playing is
flagged. Both are flags; nothing is deleted, and the analysis recomputes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import timedelta

from django.db import IntegrityError, transaction
from django.utils import timezone

from studyapp.models import Assignment, Participant, Rating, Study, System


class RatingRejected(Exception):
    """A rating that must not be stored; ``status`` is the HTTP status to answer with."""

    def __init__(self, message: str, status: int = 400) -> None:
        super().__init__(message)
        self.status = status


@dataclass(frozen=True)
class ClientTimes:
    """What the participant's browser reports, in seconds after the clip's page was shown."""

    started_s: float | None = None  # the video began playing
    ended_s: float | None = None  # the video reached its end
    answered_s: float | None = None  # the rating was clicked or keyed
    played_until_s: float | None = None  # the video's position at the answer


def current_assignment(participant: Participant) -> Assignment | None:
    """The first clip the participant has not rated yet, or None when all are rated."""
    return (participant.assignments.filter(rating__isnull=True).select_related("stimulus")
            .order_by("position").first())


def answered_early(assignment: Assignment, answered_at, times: ClientTimes) -> bool:
    """True when the clip cannot have finished playing before the answer.

    The server's own clock decides when it can (less time passed since it sent the page
    than the clip lasts); otherwise the browser's report of the video's end does.
    """
    duration = assignment.stimulus.duration_s or 0.0
    if assignment.shown_at is not None and answered_at - assignment.shown_at < timedelta(seconds=duration):
        return True
    if times.ended_s is None:
        return True
    return times.answered_s is not None and times.answered_s < times.ended_s


def _exclusion(study: Study, system: System, value: int) -> str:
    if system.role == System.Role.BAD and value >= study.bad_cutoff():
        return "rated a BAD clip high"
    if system.role == System.Role.NATURAL and value < study.natural_cutoff():
        return "rated a NAT clip low"
    return ""


def record_rating(participant: Participant, assignment_token: str, value: int, times: ClientTimes) -> Rating:
    """Store the rating of the participant's current clip, or raise RatingRejected (nothing stored)."""
    study = participant.study
    if value not in study.scale:
        raise RatingRejected(f"rating {value} is outside the scale {study.scale_min}-{study.scale_max}")
    with transaction.atomic():
        participant = Participant.objects.select_for_update().get(pk=participant.pk)
        if participant.finished_at is not None:
            raise RatingRejected("this participant has already finished the study", status=409)
        assignment = (Assignment.objects.select_related("stimulus__system")
                      .filter(participant=participant, token=assignment_token).first())
        if assignment is None:
            raise RatingRejected("that clip is not assigned to this participant", status=403)
        if Rating.objects.filter(assignment=assignment).exists():
            raise RatingRejected("that clip has already been rated", status=409)
        current = current_assignment(participant)
        if current is None or current.pk != assignment.pk:
            raise RatingRejected("that clip is not the one on screen now", status=409)
        now = timezone.now()
        early = answered_early(assignment, now, times)
        try:
            with transaction.atomic():
                rating = Rating.objects.create(
                    assignment=assignment, value=value, client_started_s=times.started_s,
                    client_ended_s=times.ended_s, client_answered_s=times.answered_s,
                    played_until_s=times.played_until_s, answered_before_end=early)
        except IntegrityError:  # a second submission racing this one
            raise RatingRejected("that clip has already been rated", status=409) from None
        reason = _exclusion(study, assignment.stimulus.system, value)
        if reason and not participant.excluded:
            participant.excluded, participant.exclusion_reason = True, reason
        if current_assignment(participant) is None:
            participant.finished_at = now
        participant.last_seen = now
        participant.save(update_fields=["excluded", "exclusion_reason", "finished_at", "last_seen"])
    return rating


EXPORT_COLUMNS = (
    "participant", "system", "stimulus", "task", "control_class", "value", "scale_min", "scale_max",
    "clip_duration_s", "shown_at", "answered_at", "client_started_s", "client_ended_s", "client_answered_s",
    "played_until_s", "answered_before_end",
    "excluded_participant", "discarded_early", "exclusion_reason",
)


def ratings_rows(study: Study) -> list[dict]:
    """The study's ratings in the schema of docs/ratings-schema.md, one dict per rating."""
    ratings = (Rating.objects.filter(assignment__participant__study=study)
               .select_related("assignment__participant", "assignment__stimulus__system",
                               "assignment__stimulus__control")
               .order_by("answered_at", "pk"))
    rows = []
    for rating in ratings:
        assignment = rating.assignment
        participant, stimulus = assignment.participant, assignment.stimulus
        early = rating.answered_before_end
        discarded = early and study.discard_early and not participant.excluded
        rows.append({
            "participant": participant.code,
            "system": stimulus.system.export_name,
            "stimulus": stimulus.token,
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
            "answered_before_end": early,
            "excluded_participant": participant.excluded,
            "discarded_early": discarded,
            "exclusion_reason": participant.exclusion_reason or ("answered before clip end" if discarded else ""),
        })
    return rows
