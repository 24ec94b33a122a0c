"""Recording a participant's rating, flagging exclusions, and the ratings table.

The rules are MoGlow Sec. 5.2's, as ``analysis.exclusions`` applies them: a participant
who rates any BAD clip at or above the study's (rescaled) BAD threshold, or any NAT clip
below its NAT threshold, is excluded; a rating given before its clip finished playing is
flagged. Both are flags; nothing is deleted, and the analysis recomputes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from django.db import IntegrityError, transaction
from django.db.models import F
from django.utils import timezone

from studyapp.designs.instructed_checks import failure_changes, passed
from studyapp.models import Assignment, Participant, Rating, Study, System
from studyapp.participants.assignment import last_seen_is_stale


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


class AnsweredTooSoon(RatingRejected):
    """An answer that arrived sooner after its page was sent than the clip lasts."""

    def __init__(self, waited: timedelta, duration_s: float) -> None:
        super().__init__(f"Please watch the clip to its end before you answer: it lasts {duration_s:.1f} s and "
                         f"your answer came {waited.total_seconds():.1f} s after it was sent.", status=409)


def _sooner_than_clip(shown_at: datetime | None, clip_seconds: float | None, answered_at: datetime) -> timedelta | None:
    """How long after the server sent the clip's page (``shown_at``) the answer came, if
    that is less than the clip lasts."""
    if shown_at is None:
        return None
    waited = answered_at - shown_at
    return waited if waited < timedelta(seconds=clip_seconds or 0.0) else None


def answered_early(shown_at: datetime | None, clip_seconds: float | None, answered_at: datetime,
                   times: ClientTimes) -> bool:
    """True when a clip of ``clip_seconds`` shown at ``shown_at`` cannot have finished playing before the answer.

    The server's own clock decides when it can (less time passed since it sent the page
    than the clip lasts); otherwise the browser's report of the video's end does.
    """
    if _sooner_than_clip(shown_at, clip_seconds, answered_at) is not None:
        return True
    if times.ended_s is None:
        return True
    return times.answered_s is not None and times.answered_s < times.ended_s


def exclusion(study: Study, role: str, value: int) -> str:
    """Why rating a clip of a system of ``role`` with ``value`` excludes the participant ("" if it does not)."""
    if role == System.Role.BAD and value >= study.bad_cutoff():
        return "rated a BAD clip high"
    if role == System.Role.NATURAL and value < study.natural_cutoff():
        return "rated a NAT clip low"
    return ""


def record_rating(participant: Participant, assignment_token: str, value: int, times: ClientTimes) -> Rating:
    """Store the rating of the participant's current clip, or raise RatingRejected (nothing stored)."""
    study = participant.study
    if participant.finished_at is not None:  # the last page answered, or stopped with pages left
        raise RatingRejected("this participant has already finished the study", status=409)
    if value not in study.scale:
        raise RatingRejected(f"rating {value} is outside the scale {study.scale_min}-{study.scale_max}")
    try:
        with transaction.atomic():
            rating = _store_rating(study, participant, assignment_token, value, times)
    except IntegrityError:  # a second submission racing this one; the transaction stored nothing
        raise RatingRejected("that clip has already been rated", status=409) from None
    except AnsweredTooSoon:  # counted outside the transaction, which stored nothing
        Participant.objects.filter(pk=participant.pk).update(refused_early=F("refused_early") + 1)
        raise
    return rating


def _store_rating(study: Study, participant: Participant, assignment_token: str, value: int,
                  times: ClientTimes) -> Rating:
    # The clip on screen is the first unrated one; the second tells whether any is left.
    # Locking their rows orders the participant's own concurrent requests (two tabs, a
    # double click) and no one else's; a race past them ends at the rating's unique
    # assignment (IntegrityError). Of the clip's stimulus only its length and system's role are needed.
    unrated = list(participant.assignments.filter(rating__isnull=True).order_by("position")
                   .annotate(clip_seconds=F("stimulus__duration_s"), system_role=F("stimulus__system__role"))
                   .select_for_update(of=("self",))[:2])
    if not unrated:
        raise RatingRejected("this participant has already finished the study", status=409)
    if unrated[0].token != assignment_token:
        raise refusal(participant, assignment_token)
    assignment, now = unrated[0], timezone.now()
    if study.require_full_play and (waited := _sooner_than_clip(assignment.shown_at, assignment.clip_seconds,
                                                                now)) is not None:
        raise AnsweredTooSoon(waited, assignment.clip_seconds)
    rating = Rating.objects.create(
        assignment=assignment, value=value, client_started_s=times.started_s, client_ended_s=times.ended_s,
        client_answered_s=times.answered_s, played_until_s=times.played_until_s,
        answered_before_end=answered_early(assignment.shown_at, assignment.clip_seconds, now, times))
    changes = {"finished_at": now} if len(unrated) == 1 else {}
    if assignment.expected and not passed(study, [assignment.expected], [value]):
        changes.update(failure_changes(study, participant, now))
    if "finished_at" not in changes and unrated[1].shown_at is None:
        # The answer leads straight to the next clip's page: marking it shown in this
        # transaction spares that page a write of its own (a second commit per rating).
        Assignment.objects.filter(pk=unrated[1].pk).update(shown_at=now)
    if changes or last_seen_is_stale(participant, now):
        Participant.objects.filter(pk=participant.pk).update(last_seen=now, **changes)
    reason = "" if assignment.expected else exclusion(study, assignment.system_role, value)
    if reason and not participant.excluded:  # the first reason stays
        Participant.objects.filter(pk=participant.pk, excluded=False).update(excluded=True, exclusion_reason=reason)
    return rating


def refusal(participant: Participant, assignment_token: str) -> RatingRejected:
    """Why ``assignment_token`` is not the clip on screen (asked only when it is not)."""
    assignment = Assignment.objects.filter(participant=participant, token=assignment_token).first()
    if assignment is None:
        return RatingRejected("that clip is not assigned to this participant", status=403)
    if Rating.objects.filter(assignment=assignment).exists():
        return RatingRejected("that clip has already been rated", status=409)
    return RatingRejected("that clip is not the one on screen now", status=409)


EXPORT_COLUMNS = (
    "participant", "system", "stimulus", "task", "control_class", "value", "scale_min", "scale_max",
    "clip_duration_s", "shown_at", "answered_at", "client_started_s", "client_ended_s", "client_answered_s",
    "played_until_s", "answered_before_end",
    "excluded_participant", "discarded_early", "exclusion_reason",
)
_SCALE_COLUMNS = ("value", "scale_min", "scale_max")
# The page structure each design adds in front (docs/ratings-schema.md); pairwise rows carry no scale.
DESIGN_COLUMNS = {
    Study.Design.SINGLE: (),
    Study.Design.SIDE_BY_SIDE: ("design", "page", "position"),
    Study.Design.PAIRWISE: ("design", "page", "side", "answer", "strength"),
}


def export_columns(study: Study) -> tuple[str, ...]:
    """The columns of the study's ratings table, by its design."""
    columns = EXPORT_COLUMNS
    if study.design == Study.Design.PAIRWISE:
        columns = tuple(c for c in columns if c not in _SCALE_COLUMNS)
    return (*DESIGN_COLUMNS[study.design], *columns)


def ratings_rows(study: Study) -> list[dict]:
    """The study's ratings in the schema of docs/ratings-schema.md, one dict per rating.

    Instructed checks are left out: their answers were dictated, not given."""
    ratings = (Rating.objects.filter(assignment__participant__study=study, assignment__expected="")
               .select_related("assignment__participant", "assignment__stimulus__system",
                               "assignment__stimulus__control")
               .order_by("answered_at", "pk"))
    columns = export_columns(study)
    rows = []
    for rating in ratings:
        assignment = rating.assignment
        participant, stimulus = assignment.participant, assignment.stimulus
        row = {
            "design": study.design,
            "page": assignment.page + 1,
            "position": assignment.slot,
            "side": "left" if assignment.slot == Assignment.LEFT else "right",
            "answer": rating.answer,
            "strength": rating.strength,
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
            "answered_before_end": rating.answered_before_end,
            "excluded_participant": participant.excluded,
            "exclusion_reason": participant.exclusion_reason,
        }
        rows.append({column: row[column] for column in columns if column in row})
    _flag_discarded(study, rows)
    return rows


def _flag_discarded(study: Study, rows: list[dict]) -> None:
    """Add ``discarded_early`` and ``exclusion_reason``: an early answer discards its
    clip's rating, and on a pairwise page the whole page (its one answer)."""
    pairwise = study.design == Study.Design.PAIRWISE
    early_pages = {(row["participant"], row["page"]) for row in rows if pairwise and row["answered_before_end"]}
    for row in rows:
        early = row["answered_before_end"] or (pairwise and (row["participant"], row["page"]) in early_pages)
        discarded = early and study.discard_early and not row["excluded_participant"]
        row["discarded_early"] = discarded
        row["exclusion_reason"] = row["exclusion_reason"] or ("answered before clip end" if discarded else "")
