"""Which pages a new participant answers: balanced across stimuli, with attention checks.

In the single design a participant gets ``clips_per_participant`` clips, one a page:
``bad_checks`` BAD clips and ``natural_checks`` NAT clips as attention checks, and the
rest from every non-BAD system, least-loaded first, among equally loaded ones of the
system they have been given least (so each participant sees the systems evenly), ties
broken at random, skipping stimuli that have reached the study's target. The rated clips
are shuffled and the checks put at random positions. Side-by-side and pairwise pages
are planned by ``page_assignment``; instructed checks are added by ``instructed_checks``.

A stimulus's load counts the ratings that will be kept (not from an excluded participant,
not given before the clip ended) plus the clips reserved by participants who are still
active. Allocation runs inside one transaction that first locks the study row (on
PostgreSQL; SQLite's IMMEDIATE transactions serialise writers anyway), so two participants
arriving together see each other's reservations and never push a stimulus past its target.
"""

from __future__ import annotations

import random
from collections import Counter
from datetime import datetime, timedelta

from django.db import transaction
from django.db.models import Count, Q
from django.utils import timezone

from studyapp.designs.instructed_checks import add_instructed_checks
from studyapp.designs.page_assignment import PlannedPage, page_loads, page_orders, pairwise_plan, side_by_side_plan
from studyapp.models import Assignment, Participant, Stimulus, Study, System


class StudyFull(Exception):
    """Every stimulus has reached its target number of ratings."""


class StudyNotReady(Exception):
    """The study has no rendered clips to rate yet."""


def _reservation(study: Study) -> timedelta:
    """How long an unfinished participant's unrated clips stay reserved after ``last_seen``:
    ``reservation_minutes`` and a hundredth, because ``last_seen`` is written only when it
    is older than that hundredth (``last_seen_is_stale``)."""
    return timedelta(minutes=study.reservation_minutes) * 1.01


def last_seen_is_stale(participant: Participant, now: datetime) -> bool:
    """Whether ``last_seen`` needs writing: older than a hundredth of the reservation time
    (54 s at 90 minutes), so that a participant going from clip to clip costs no write."""
    return now - participant.last_seen > timedelta(minutes=participant.study.reservation_minutes) / 100


def is_idle(participant: Participant, now: datetime) -> bool:
    """Away longer than their reservation: their unrated clips may have gone to others."""
    return participant.finished_at is None and now - participant.last_seen > _reservation(participant.study)


def stimulus_loads(study: Study) -> dict[int, int]:
    """Load of each rendered stimulus of the study: kept ratings + live reservations."""
    cutoff = timezone.now() - _reservation(study)
    kept = Q(assignments__rating__isnull=False)
    if study.discard_early:
        kept &= Q(assignments__rating__answered_before_end=False)
    counted = Q(assignments__participant__excluded=False) & (
        kept
        | Q(assignments__rating__isnull=True, assignments__participant__finished_at__isnull=True,
            assignments__participant__last_seen__gte=cutoff)
    )
    rows = (Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE)
            .annotate(load=Count("assignments", filter=counted)).values_list("id", "load"))
    return dict(rows)


def _least_loaded(candidates: list[Stimulus], loads: dict[int, int], count: int, rng: random.Random,
                  cap: int | None = None, seen: Counter | None = None) -> list[Stimulus]:
    """``count`` of the candidates under ``cap``, least loaded first; among equally loaded
    ones, of the system the participant has been given least so far (``seen``, updated),
    so that one participant sees the systems as evenly as the loads allow."""
    seen = Counter() if seen is None else seen
    eligible = [s for s in candidates if cap is None or loads[s.id] < cap]
    rng.shuffle(eligible)  # ties at random: min() takes the first
    chosen: list[Stimulus] = []
    while eligible and len(chosen) < count:
        best = min(eligible, key=lambda s: (loads[s.id], seen[s.system_id]))
        eligible.remove(best)
        chosen.append(best)
        seen[best.system_id] += 1
    return chosen


def _plan(study: Study, loads: dict[int, int], rng: random.Random) -> list[tuple[Stimulus, bool]]:
    """(stimulus, is_check) in presentation order."""
    rendered = list(Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).select_related("system"))
    if not any(s.system.role != System.Role.BAD for s in rendered):
        raise StudyNotReady("no clips have been rendered for this study yet")
    by_role = {role: [s for s in rendered if s.system.role == role] for role in System.Role.values}
    # BAD clips are never analysed, so they have no target; NAT clips are (NAT is a
    # system like the others), so NAT checks too stop at the target.
    seen: Counter = Counter()
    checks = (_least_loaded(by_role[System.Role.BAD], loads, study.bad_checks, rng, seen=seen)
              + _least_loaded(by_role[System.Role.NATURAL], loads, study.natural_checks, rng,
                              cap=study.ratings_per_stimulus, seen=seen))
    taken = {s.id for s in checks}
    pool = [s for s in rendered if s.system.role != System.Role.BAD and s.id not in taken]
    rated = _least_loaded(pool, loads, study.clips_per_participant - len(checks), rng, cap=study.ratings_per_stimulus,
                          seen=seen)
    if not rated:
        raise StudyFull("every clip of this study has its target number of ratings")
    order: list[tuple[Stimulus, bool]] = [(s, False) for s in rated]
    rng.shuffle(order)
    for stimulus in checks:
        order.insert(rng.randint(0, len(order)), (stimulus, True))
    return order


def _training_clips(study: Study, exclude: set[int], rng: random.Random) -> list[int]:
    """Practice clips: one per system in turn, a BAD one first when there is one (so that
    every participant sees what broken motion looks like), none among the rated ones."""
    per_system: dict[int, list[int]] = {}
    for stimulus in Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).exclude(id__in=exclude):
        per_system.setdefault(stimulus.system_id, []).append(stimulus.id)
    for ids in per_system.values():
        rng.shuffle(ids)
    systems = list(per_system)
    rng.shuffle(systems)
    bad = set(System.objects.filter(study=study, role=System.Role.BAD).values_list("id", flat=True))
    systems.sort(key=lambda system: system not in bad)  # stable: the shuffle orders the rest
    chosen: list[int] = []
    while len(chosen) < study.training_clips and any(per_system.values()):
        for system in systems:
            if per_system[system] and len(chosen) < study.training_clips:
                chosen.append(per_system[system].pop())
    rng.shuffle(chosen)  # the BAD example at a random place among them
    return chosen


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


def _pages(study: Study, rng: random.Random) -> list[PlannedPage]:
    """The participant's pages in order, by the study's design, instructed checks included."""
    if study.design == Study.Design.SINGLE:
        pages = [PlannedPage([stimulus], is_check) for stimulus, is_check in _plan(study, stimulus_loads(study), rng)]
    else:
        rendered = list(Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).select_related("system"))
        if not any(s.system.role != System.Role.BAD for s in rendered):
            raise StudyNotReady("no clips have been rendered for this study yet")
        plan = side_by_side_plan if study.design == Study.Design.SIDE_BY_SIDE else pairwise_plan
        cutoff = timezone.now() - _reservation(study)
        pages = plan(study, rendered, page_loads(study, cutoff), page_orders(study), rng)
        if not pages:
            raise StudyFull("every page of this study has its target number of answers")
    return add_instructed_checks(study, pages, rng)


def _release_full(participant: Participant, study: Study, now: datetime) -> None:
    """Delete the idle participant's unrated pages that others have filled to the target
    meanwhile (loads computed without this participant: their last_seen is stale)."""
    unrated = (participant.assignments.filter(rating__isnull=True, is_check=False)
               .select_related("stimulus__system").order_by("position"))
    if study.design == Study.Design.SINGLE:
        loads, keyed = Counter(stimulus_loads(study)), [(a.stimulus_id, [a]) for a in unrated]
    else:
        loads = page_loads(study, now - _reservation(study))
        pages: dict[int, list[Assignment]] = {}
        for assignment in unrated:
            pages.setdefault(assignment.page, []).append(assignment)
        keyed = [(PlannedPage([a.stimulus for a in page]).key, page) for page in pages.values()]
    for key, assignments in keyed:
        if loads[key] >= study.ratings_per_stimulus:
            Assignment.objects.filter(pk__in=[a.pk for a in assignments]).delete()
        else:
            loads[key] += 1


def enrol(study: Study, platform_id: str, platform_data: dict, user_agent: str = "",
          rng: random.Random | None = None) -> Participant:
    """Create a participant with their pages, or raise StudyFull / StudyNotReady (nothing saved)."""
    rng = rng or random.SystemRandom()
    with transaction.atomic():
        Study.objects.select_for_update().get(pk=study.pk)
        pages = _pages(study, rng)
        participant = Participant.objects.create(
            study=study, platform_id=platform_id, platform_data=platform_data, user_agent=user_agent[:300],
            training=_training_clips(study, {s.id for page in pages for s in page.clips}, rng))
        clips = [(index, slot, stimulus, page) for index, page in enumerate(pages)
                 for slot, stimulus in enumerate(page.clips, start=1)]
        Assignment.objects.bulk_create([
            Assignment(participant=participant, stimulus=stimulus, position=position, page=index, slot=slot,
                       is_check=page.is_check, expected=page.expected[slot - 1] if page.expected else "")
            for position, (index, slot, stimulus, page) in enumerate(clips)
        ])
    return participant
