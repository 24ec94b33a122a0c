"""Recording the answer to a side-by-side or pairwise page: all its clips at once.

A side-by-side page stores one rating per clip (its slider's value); a pairwise page
stores the same answer (left, right or none, with its strength) on both its clips'
ratings, as the ratings table carries it. Each clip's own timings judge whether it was
answered before it finished playing (``ratings.answered_early``).

Attention checks, per design (documented in docs/running-a-study.md): on a side-by-side
page the study's thresholds, rescaled to its scale, apply to every clip as in the
single design (on 0-100 with the defaults: a NAT clip below 25 or a BAD clip at 75 or
above excludes the participant, as GENEA does); on a pairwise page showing a BAD clip,
preferring it excludes. Instructed checks count failures instead (``instructed_checks``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from django.db import IntegrityError, transaction
from django.utils import timezone

from studyapp.designs.instructed_checks import failure_changes, passed
from studyapp.designs.ratings import ClientTimes, RatingRejected, answered_early, current_assignment, exclusion, refusal
from studyapp.models import Assignment, Participant, Rating, Study, System
from studyapp.participants.assignment import last_seen_is_stale

SIDE_OF_SLOT = {Assignment.LEFT: Rating.Answer.LEFT, Assignment.RIGHT: Rating.Answer.RIGHT}


@dataclass(frozen=True)
class PageAnswer:
    """What a page's form sent: slider values per slot (side-by-side) or the preference (pairwise)."""

    times: dict[int, ClientTimes]  # per slot
    values: dict[int, int] = field(default_factory=dict)
    answer: str = ""
    strength: int | None = None


def current_page(participant: Participant) -> list[Assignment]:
    """The clips of the first page with an unrated clip, in slot order (empty when all are answered)."""
    first = current_assignment(participant)
    if first is None:
        return []
    return list(participant.assignments.filter(page=first.page).select_related("stimulus__system").order_by("slot"))


def _check(study: Study, answer: PageAnswer) -> None:
    """Refuse a malformed answer before touching the database."""
    if study.design == Study.Design.SIDE_BY_SIDE:
        for slot, value in answer.values.items():
            if value not in study.scale:
                raise RatingRejected(f"the rating of clip {slot} ({value}) is outside the scale "
                                     f"{study.scale_min}-{study.scale_max}")
        return
    if answer.answer not in Rating.Answer.values:
        raise RatingRejected(f"the answer must be one of {', '.join(Rating.Answer.values)}, not {answer.answer[:20]!r}")
    if answer.answer == Rating.Answer.NONE or not study.preference_strengths:
        if answer.strength is not None:
            raise RatingRejected("a strength goes with a preference for one clip, and only where the study asks it")
    elif answer.strength not in study.strengths:
        raise RatingRejected(f"the strength of the preference must be a whole number from 1 to "
                             f"{study.preference_strengths}")


def record_page(participant: Participant, page_token: str, answer: PageAnswer) -> list[Rating]:
    """Store the answer to the participant's current page, or raise RatingRejected (nothing stored)."""
    study = participant.study
    if participant.finished_at is not None:  # the last page answered, or stopped with pages left
        raise RatingRejected("this participant has already finished the study", status=409)
    _check(study, answer)
    try:
        with transaction.atomic():
            return _store_page(study, participant, page_token, answer)
    except IntegrityError:  # a second submission racing this one; the transaction stored nothing
        raise RatingRejected("that page has already been answered", status=409) from None


def _store_page(study: Study, participant: Participant, page_token: str, answer: PageAnswer) -> list[Rating]:
    # As for single clips: locking the unrated clips orders the participant's own
    # concurrent requests, and the rating's unique assignment stops a race past them.
    unrated = list(participant.assignments.filter(rating__isnull=True).select_related("stimulus__system")
                   .select_for_update(of=("self",)).order_by("position"))
    if not unrated:
        raise RatingRejected("this participant has already finished the study", status=409)
    if unrated[0].token != page_token:
        raise refusal(participant, page_token)
    page = [a for a in unrated if a.page == unrated[0].page]
    if study.design == Study.Design.SIDE_BY_SIDE and set(answer.values) != {a.slot for a in page}:
        missing = sorted({a.slot for a in page} - set(answer.values))
        raise RatingRejected(f"every clip on the page needs a rating; missing: clip {', '.join(map(str, missing))}"
                             if missing else "ratings were sent for clips that are not on this page")
    now = timezone.now()
    ratings = Rating.objects.bulk_create([
        Rating(assignment=a, value=answer.values.get(a.slot), answer=answer.answer, strength=answer.strength,
               client_started_s=times.started_s, client_ended_s=times.ended_s,
               client_answered_s=times.answered_s, played_until_s=times.played_until_s,
               answered_before_end=answered_early(a.shown_at, a.stimulus.duration_s, now, times))
        for a in page for times in [answer.times.get(a.slot, ClientTimes())]
    ])
    changes: dict = {"finished_at": now} if len(unrated) == len(page) else {}
    expected = [a.expected for a in page]
    if any(expected) and not passed(study, expected, [answer.values.get(a.slot) for a in page], answer.answer):
        changes.update(failure_changes(study, participant, now))
    if changes or last_seen_is_stale(participant, now):
        Participant.objects.filter(pk=participant.pk).update(last_seen=now, **changes)
    reason = "" if any(expected) else _page_exclusion(study, page, answer)
    if reason and not participant.excluded:  # the first reason stays
        Participant.objects.filter(pk=participant.pk, excluded=False).update(excluded=True, exclusion_reason=reason)
    return ratings


def _page_exclusion(study: Study, page: list[Assignment], answer: PageAnswer) -> str:
    if study.design == Study.Design.SIDE_BY_SIDE:
        return next((reason for a in page if (reason := exclusion(study, a.stimulus.system.role, answer.values[a.slot]))), "")
    preferred = next((a for a in page if SIDE_OF_SLOT.get(a.slot) == answer.answer), None)
    if preferred is not None and preferred.stimulus.system.role == System.Role.BAD:
        return "preferred a BAD clip"
    return ""
