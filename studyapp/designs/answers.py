"""Storing the answer to a participant's current page, the same way in every design.

The page's design reads and checks the form (``Design.read_answer``, ``check_answer``);
this module stores one rating per clip of the page, or refuses the answer (nothing
stored):

- the full-play rule: with ``require_full_play`` (as in the study's rules), an answer
  that comes sooner after the page was sent than its clips last is refused with 409 and
  counted (``Participant.refused_early``); on a page of several clips the longest one
  decides, the least time in which every clip can have played to its end;
- every rating is flagged ``answered_before_end`` where its clip cannot have finished
  before the answer (by the server's clock, or else by the browser's report);
- an instructed check's answer counts a failure where it is not the one asked for;
- an answer that fails an attention check excludes the participant (the study's rules,
  ``designs.rules``, applied by the design to this one answer).

Both are flags; nothing is deleted, and the analysis recomputes them from the ratings
table with the same rules.
"""

from __future__ import annotations

from datetime import datetime, timedelta

from django.db import IntegrityError, transaction
from django.db.models import F
from django.http import QueryDict
from django.utils import timezone

from studyapp.designs.design import Answer, ClientTimes, OnPage, TIME_FIELDS
from studyapp.designs.registry import design_of
from studyapp.designs.rules import StudyRules
from studyapp.models import Assignment, Participant, Rating, Study, export_name
from studyapp.participants.assignment import last_seen_is_stale
from studyapp.participants.refusal import AnswerRefused
from studyapp.server.db.compiled_queries import CompiledQuery
from studyapp.server.db.round_trips import insert, pipeline, update, updated_count


class AnsweredTooSoon(AnswerRefused):
    """An answer that arrived sooner after its page was sent than its clips last."""

    def __init__(self, waited: timedelta, longest_s: float, clips: int) -> None:
        what = "the clip to its end" if clips == 1 else "every clip to its end"
        lasts = "it lasts" if clips == 1 else "the longest lasts"
        super().__init__(f"Please watch {what} before you answer: {lasts} {longest_s:.1f} s and your answer came "
                         f"{waited.total_seconds():.1f} s after it was sent.", status=409)


def optional_seconds(form: QueryDict, name: str) -> float | None:
    """A client time in seconds from the posted form, None when empty."""
    text = form.get(name, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise AnswerRefused(f"{name} must be a number of seconds, not {text[:20]!r}") from None
    if not 0 <= value < 1e6:
        raise AnswerRefused(f"{name} must lie between 0 and a million seconds, not {value}")
    return value


def client_times(form: QueryDict, suffix: str = "") -> ClientTimes:
    """The browser's times of one clip (fields ``started_s<suffix>``, ...)."""
    return ClientTimes(*(optional_seconds(form, f"{name}{suffix}") for name in TIME_FIELDS))


def whole_number(form: QueryDict, name: str, what: str) -> int | None:
    """A whole number from the posted form, None when empty."""
    text = form.get(name, "").strip()
    if not text:
        return None
    try:
        return int(text)
    except ValueError:
        raise AnswerRefused(f"{what} must be a whole number, not {text[:20]!r}") from None


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


def failure_changes(study: Study, participant: Participant, now: datetime) -> dict:
    """The participant's fields after one more failed instructed check: the count, and the
    end of their session when it reaches the study's limit."""
    failed = participant.failed_checks + 1
    changes: dict = {"failed_checks": failed}
    if study.stop_after_failed_checks and failed >= study.stop_after_failed_checks:
        changes.update(stopped_at=now, finished_at=now)
    return changes


def record_answer(participant: Participant, answer: Answer) -> None:
    """Store the answer to the participant's current page, or raise AnswerRefused (nothing
    stored); ``participant`` is updated in memory as the answer changed it."""
    if participant.finished_at is not None:  # the last page answered, or stopped with pages left
        raise AnswerRefused("this participant has already finished the study", status=409)
    try:
        # The server waits for the database twice (round_trips): for the page's clips, sent
        # with the transaction's start, and for the commit, sent with the writes.
        with pipeline(), transaction.atomic():
            _store(participant.study, participant, answer)
    except IntegrityError:  # a second submission racing this one; the transaction stored nothing
        raise AnswerRefused(f"that {design_of(participant.study).page_word.lower()} has already been answered",
                            status=409) from None
    except AnsweredTooSoon:  # counted outside the transaction, which stored nothing
        Participant.objects.filter(pk=participant.pk).update(refused_early=F("refused_early") + 1)
        raise


# The participant's unrated clips in order, locked (see _store), with what an answer's checks need.
_unrated_for_update = CompiledQuery(
    lambda participant: Assignment.objects.filter(participant_id=participant, rating__isnull=True).order_by("position")
    .annotate(clip_seconds=F("stimulus__duration_s"), system_role=F("stimulus__system__role"),
              system_name=F("stimulus__system__name"))
    .select_for_update(of=("self",)), int)


def _store(study: Study, participant: Participant, answer: Answer) -> None:
    design = design_of(study)
    # The page on screen is the first with an unrated clip. Locking the unrated clips
    # orders the participant's own concurrent requests (two tabs, a double click) and no
    # one else's; a race past them ends at the rating's unique assignment (IntegrityError).
    unrated = _unrated_for_update(participant.pk)
    if not unrated:
        raise AnswerRefused("this participant has already finished the study", status=409)
    if unrated[0].token != answer.page:
        raise refusal(participant, answer.page, design.page_word.lower())
    page = [a for a in unrated if a.page == unrated[0].page]
    design.check_answer(study, answer, [a.slot for a in page])
    now = timezone.now()
    rules = StudyRules.of(study)
    if rules.refuse_before_clip_end:
        late = [(waited, a.clip_seconds) for a in page
                if (waited := _sooner_than_clip(a.shown_at, a.clip_seconds, now)) is not None]
        if late:
            raise AnsweredTooSoon(late[0][0], max(a.clip_seconds or 0.0 for a in page), len(page))
    insert([
        Rating(assignment=a, value=answer.values.get(a.slot), answer=answer.choice, strength=answer.strength,
               client_started_s=times.started_s, client_ended_s=times.ended_s, client_answered_s=times.answered_s,
               played_until_s=times.played_until_s, reasons=list(answer.reasons), other_reason=answer.other_reason,
               answered_before_end=answered_early(a.shown_at, a.clip_seconds, now, times))
        for a in page for times in [answer.times.get(a.slot, ClientTimes())]
    ])
    changes: dict = {"finished_at": now} if len(unrated) == len(page) else {}
    expected = [a.expected for a in page]
    if any(expected) and not design.follows_instruction(study, expected, answer):
        changes.update(failure_changes(study, participant, now))
    following = [a.pk for a in unrated[len(page):] if a.page == unrated[len(page)].page and a.shown_at is None] \
        if "finished_at" not in changes else []
    if following:
        # The answer leads straight to the next page: marking it shown in this
        # transaction spares that page a write of its own (a second commit per answer).
        update(Assignment.objects.filter(pk__in=following), shown_at=now)
    if changes or last_seen_is_stale(participant, now):
        changes["last_seen"] = now
        update(Participant.objects.filter(pk=participant.pk), **changes)
    on_page = [OnPage(a, export_name(a.system_role, a.system_name), a.clip_seconds or 0.0) for a in page]
    reason = "" if any(expected) else design.exclusion_reason(rules.exclusion, study, on_page, answer)
    if reason and not participant.excluded:  # the first reason stays
        if updated_count(Participant.objects.filter(pk=participant.pk, excluded=False), excluded=True,
                         exclusion_reason=reason):
            changes.update(excluded=True, exclusion_reason=reason)
    # The participant as stored now, so that the next page is read from it without a query.
    for name, value in changes.items():
        setattr(participant, name, value)


def refusal(participant: Participant, token: str, unit: str) -> AnswerRefused:
    """Why ``token`` does not name the page on screen (asked only when it does not)."""
    assignment = Assignment.objects.filter(participant=participant, token=token).first()
    if assignment is None:
        return AnswerRefused(f"that {unit} is not assigned to this participant", status=403)
    if Rating.objects.filter(assignment=assignment).exists():
        return AnswerRefused(f"that {unit} has already been answered", status=409)
    return AnswerRefused(f"that {unit} is not the one on screen now", status=409)
