"""Which pages a new participant answers, and the pages they hold while they take part.

The study's design plans the pages (``Design.plan``: which clips, on which slots, which
are attention checks) from the loads of the pages so far, and the practice clips shown
before them; the study's instructed checks are then added among the pages, at random
places after the first, each repeating one of the rated pages and saying what answer to
give (the design says what it asks). The pages of a participant number the study's
pages per participant, instructed checks included.

A page's load counts the answers that will be kept plus the pages reserved by
participants who are still active. Enrolment runs inside one transaction that first
locks the study row (on PostgreSQL; SQLite's IMMEDIATE transactions serialise writers
anyway), so two participants arriving together see each other's reservations and never
push a page past its target.
"""

from __future__ import annotations

import random
from datetime import datetime, timedelta

from django.db import transaction
from django.utils import timezone

from studyapp.designs.design import Design, PlannedPage
from studyapp.designs.registry import design_of
from studyapp.models import Assignment, Participant, Stimulus, Study, System
from studyapp.participants.study_cache import rendered_clips
from studyapp.server.db.round_trips import draw_id, insert, lock_rows, pipeline


class StudyFull(Exception):
    """Every stimulus has reached its target number of ratings."""


class StudyNotReady(Exception):
    """The study has no rendered clips to rate yet."""


def _reservation(study: Study) -> timedelta:
    """How long an unfinished participant's unrated clips stay reserved after ``last_seen``:
    ``reservation_minutes`` and a hundredth, because ``last_seen`` is written only when it
    is older than that hundredth (``last_seen_is_stale``)."""
    return timedelta(minutes=study.reservation_minutes) * 1.01


def active_since(study: Study, now: datetime | None = None) -> datetime:
    """The ``last_seen`` from which an unfinished participant still holds their pages."""
    return (now or timezone.now()) - _reservation(study)


def last_seen_is_stale(participant: Participant, now: datetime) -> bool:
    """Whether ``last_seen`` needs writing: older than a hundredth of the reservation time
    (54 s at 90 minutes), so that a participant going from clip to clip costs no write."""
    return now - participant.last_seen > timedelta(minutes=participant.study.reservation_minutes) / 100


def is_idle(participant: Participant, now: datetime) -> bool:
    """Away longer than their reservation: their unrated clips may have gone to others."""
    return participant.finished_at is None and now - participant.last_seen > _reservation(participant.study)


def renew_reservations(participant: Participant) -> Participant:
    """Mark the participant as active now (see ``last_seen_is_stale``); a participant back
    after ``reservation_minutes`` keeps only the unrated clips that still fit under their
    targets.

    While a participant is idle that long, their unrated clips stop counting towards the
    targets and may be given to others; rating them on return would push those stimuli
    past their targets. Attention checks are kept (BAD has no target). Unrated
    assignments are reservations, not data, so releasing one deletes it.
    """
    study = participant.study
    now = timezone.now()
    if not is_idle(participant, now):
        if last_seen_is_stale(participant, now):  # the common case: no lock, rarely a write
            Participant.objects.filter(pk=participant.pk).update(last_seen=now)
            participant.last_seen = now
        return participant
    with transaction.atomic():  # the same lock as enrol(), which may be handing these clips out
        Study.objects.select_for_update().get(pk=study.pk)
        participant = Participant.objects.select_for_update().select_related("study").get(pk=participant.pk)
        if is_idle(participant, now):  # not renewed by a request racing this one
            _release_full(participant, study, now)
            if not participant.assignments.filter(rating__isnull=True).exists():
                participant.finished_at = now
        participant.last_seen = now
        participant.save(update_fields=["last_seen", "finished_at"])
    return participant


def _pages(study: Study, design: Design, rendered: list[Stimulus], rng: random.Random) -> list[PlannedPage]:
    """The participant's pages in order, instructed checks included."""
    if not any(s.system.role != System.Role.BAD for s in rendered):
        raise StudyNotReady("no clips have been rendered for this study yet")
    loads = design.loads(study, active_since(study))
    pages = design.plan(study, rendered, loads, design.page_count(study) - study.instructed_checks, rng)
    if not pages:
        raise StudyFull(f"every {design.page_word.lower()} of this study has its target number of answers")
    rated = [page for page in pages if not page.is_check] or pages
    for _ in range(study.instructed_checks):
        clips = list(rng.choice(rated).clips)
        pages.insert(rng.randint(1, len(pages)), PlannedPage(
            clips, is_check=True, expected=design.instructed_answer(study, clips, rng)))
    return pages


def _release_full(participant: Participant, study: Study, now: datetime) -> None:
    """Delete the idle participant's unrated pages that others have filled to the target
    meanwhile (loads computed without this participant: their last_seen is stale)."""
    loads = design_of(study).loads(study, active_since(study, now))
    pages: dict[int, list[Assignment]] = {}
    for assignment in (participant.assignments.filter(rating__isnull=True, is_check=False)
                       .select_related("stimulus__system").order_by("position")):
        pages.setdefault(assignment.page, []).append(assignment)
    for assignments in pages.values():
        key = PlannedPage([a.stimulus for a in assignments]).key
        if loads[key] >= study.ratings_per_stimulus:
            Assignment.objects.filter(pk__in=[a.pk for a in assignments]).delete()
        else:
            loads[key] += 1


def enrol(study: Study, platform_id: str, platform_data: dict, user_agent: str = "",
          rng: random.Random | None = None) -> Participant:
    """Create a participant with their pages, or raise StudyFull / StudyNotReady (nothing saved)."""
    rng = rng or random.SystemRandom()
    design = design_of(study)
    # Read before the lock that every arriving participant queues for: only the loads must
    # be read under it. A clip finished meanwhile is left out of these pages; one being
    # rendered again keeps its load (``Design.loads`` counts clips whatever their status).
    rendered = rendered_clips(study)
    participant = Participant(pk=draw_id(Participant), study=study, platform_id=platform_id,
                              platform_data=platform_data, user_agent=user_agent[:300])
    # Under the lock the server waits for the database twice (round_trips): for the loads,
    # sent with the lock, and for the commit, sent with the new rows.
    with pipeline(), transaction.atomic():
        lock_rows(Study.objects.filter(pk=study.pk))
        pages = _pages(study, design, rendered, rng)
        participant.training = design.practice(study, rendered, [page for page in pages if not page.expected], rng)
        insert([participant])
        clips = [(index, slot, stimulus, page) for index, page in enumerate(pages)
                 for slot, stimulus in enumerate(page.clips, start=1)]
        insert([
            Assignment(participant=participant, stimulus=stimulus, position=position, page=index, slot=slot,
                       is_check=page.is_check, expected=page.expected[slot - 1] if page.expected else "")
            for position, (index, slot, stimulus, page) in enumerate(clips)
        ])
    return participant
