"""Assignment in every design: targets reached and never passed, positions and sides
counterbalanced, each participant's systems as even as the design allows."""

from __future__ import annotations

import random
from collections import Counter, defaultdict
from datetime import timedelta

import pytest
from django.db import connection
from django.utils import timezone

from studyapp.designs.multi_clip import page_loads
from studyapp.designs.single_pages import stimulus_loads
from studyapp.models import Assignment, Participant, Rating, Stimulus, Study, System
from studyapp.participants.assignment import StudyFull, enrol
from studyapp.participants.simulated import run_participants
from tests.study_fixtures import make_study


def an_hour_ago():
    """A cutoff that counts every participant of the test as active."""
    return timezone.now() - timedelta(hours=1)


def enrol_until_full(study: Study) -> list[Participant]:
    enrolled = []
    with pytest.raises(StudyFull):
        for i in range(200):
            enrolled.append(enrol(study, f"p{i}", {}, rng=random.Random(i)))
    return enrolled


def spread(counts) -> int:
    values = list(counts)
    return max(values) - min(values)


def page_systems(participant: Participant) -> dict[int, list[Assignment]]:
    pages = defaultdict(list)
    for a in participant.assignments.select_related("stimulus__system").order_by("position"):
        pages[a.page].append(a)
    return pages


@pytest.mark.django_db
def test_single_design_gives_each_participant_every_system_evenly():
    # 3 rated systems x 4 controls; each participant rates 6 clips besides the BAD check.
    study = make_study(controls=4, clips_per_participant=7, ratings_per_stimulus=3, bad_checks=1, natural_checks=0)
    rated = [s.id for s in Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD)]
    enrolled = enrol_until_full(study)
    assert len(enrolled) == len(rated) * study.ratings_per_stimulus // 6
    for participant in enrolled:
        systems = Counter(a.stimulus.system.name for a in participant.assignments.filter(is_check=False))
        assert systems == {"MoGlow": 2, "RNN": 2, "NAT": 2}, systems
    assert Counter(Assignment.objects.filter(stimulus_id__in=rated).values_list("stimulus_id", flat=True)) == {
        s: study.ratings_per_stimulus for s in rated}


@pytest.mark.django_db
def test_side_by_side_pages_reach_their_target_never_pass_it_and_positions_are_counterbalanced():
    study = make_study(design="side-by-side", scale_min=0, scale_max=100, controls=3,
                       pages_per_participant=2, ratings_per_stimulus=6, bad_checks=0)
    enrolled = enrol_until_full(study)
    assert len(enrolled) == 3 * 6 // 2
    loads = page_loads(study, an_hour_ago())
    assert sorted(loads.values()) == [6, 6, 6]
    for participant in enrolled:
        for page in page_systems(participant).values():
            assert sorted(a.stimulus.system.name for a in page) == ["MoGlow", "NAT", "RNN"]
            assert len({a.stimulus.control_id for a in page}) == 1
    slots = Counter(Assignment.objects.values_list("stimulus_id", "slot"))
    for stimulus in Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD):
        assert [slots[stimulus.id, slot] for slot in (1, 2, 3)] == [2, 2, 2]  # 6 pages over 3 positions


@pytest.mark.django_db
def test_pairwise_pairs_reach_their_target_sides_balance_and_each_participant_sees_systems_evenly():
    # 3 controls x 3 pairs of (MoGlow, RNN, NAT) x 2 answers = 18 pages; 3 rated pages each (+1 BAD-vs-NAT check).
    study = make_study(design="pairwise", controls=3, pages_per_participant=4, ratings_per_stimulus=2,
                       bad_checks=1)
    enrolled = enrol_until_full(study)
    assert len(enrolled) == 18 // 3
    loads = page_loads(study, an_hour_ago())
    rated_pairs = {key: n for key, n in loads.items() if len(key) == 2}
    assert len(rated_pairs) == 9 and set(rated_pairs.values()) == {2}
    for participant in enrolled:
        pages = page_systems(participant)
        checks = [p for p in pages.values() if p[0].is_check]
        assert len(checks) == 1 and sorted(a.stimulus.system.name for a in checks[0]) == ["BAD", "NAT"]
        seen = Counter(a.stimulus.system.name for p in pages.values() if not p[0].is_check for a in p)
        assert seen == {"MoGlow": 2, "RNN": 2, "NAT": 2}, seen
    sides = Counter(Assignment.objects.filter(is_check=False).values_list("stimulus_id", "slot"))
    for stimulus in Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD):
        assert abs(sides[stimulus.id, Assignment.LEFT] - sides[stimulus.id, Assignment.RIGHT]) <= 1


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design, pages, expected", [
    # 4 controls x 3 systems on one page each, 3 answers each, 2 pages a participant: 6 fit.
    ("side-by-side", 2, 6),
    # 4 controls x 3 pairs, 2 answers each, 3 pages a participant: 8 fit.
    ("pairwise", 3, 8),
])
def test_simultaneous_participants_never_pass_a_page_target_and_lose_no_answer(live_server, design, pages, expected):
    target = 3 if design == "side-by-side" else 2
    study = make_study(design=design, controls=4, pages_per_participant=pages, ratings_per_stimulus=target,
                       bad_checks=0, training_clips=0, clip_seconds=0.01, scale_min=0, scale_max=100,
                       bad_threshold=6.0, natural_threshold=0.0)
    outcomes = run_participants(f"{live_server.url}/p/{study.key}/", count=16)

    assert [o.error for o in outcomes if o.error] == []
    finished = [o for o in outcomes if o.finished]
    assert len(finished) == expected and sum(o.ratings for o in outcomes) == expected * pages
    assert all("The study is full" in o.final_page for o in outcomes if not o.finished)
    assert not Rating.objects.filter(answered_before_end=True).exists()
    assert set(page_loads(study, an_hour_ago()).values()) == {target}
    clips_per_page = 3 if design == "side-by-side" else 2
    assert Rating.objects.count() == expected * pages * clips_per_page


@pytest.mark.django_db
def test_an_idle_participant_back_after_their_page_was_filled_by_others_loses_only_that_page():
    from studyapp.participants.assignment import renew_reservations

    study = make_study(design="side-by-side", scale_min=0, scale_max=100, controls=2,
                       pages_per_participant=2, ratings_per_stimulus=1, bad_checks=0, reservation_minutes=30)
    idle = enrol(study, "idle", {})
    with pytest.raises(StudyFull):
        enrol(study, "second", {})
    Participant.objects.filter(pk=idle.pk).update(last_seen=timezone.now() - timedelta(minutes=31))
    taker = enrol(study, "second", {}, rng=random.Random(0))  # both pages again, the idle one's places free
    assert taker.assignments.values("page").distinct().count() == 2
    idle = renew_reservations(Participant.objects.get(pk=idle.pk))
    assert not idle.assignments.exists() and idle.finished_at is not None  # nothing fits under the targets now
    assert set(page_loads(study, an_hour_ago()).values()) == {1}


@pytest.mark.django_db
def test_a_clip_rendered_again_while_a_participant_waits_for_the_lock_keeps_its_load():
    # Enrolment reads the clips before it queues for the study's lock; a clip whose video
    # is being rendered again by the time it plans still counts the answers it has.
    study = make_study(controls=2, clips_per_participant=7, ratings_per_stimulus=1, bad_checks=1, natural_checks=0)
    first = enrol(study, "first", {}, rng=random.Random(0))  # every rated clip, each at its target of 1
    rendered_again = first.assignments.filter(is_check=False).first().stimulus_id
    seen = {"clips read": False, "rendered again": False}

    def render_again_once_the_clips_are_read(execute, sql, params, many, context):
        if seen["clips read"] and not seen["rendered again"]:  # the statement after the read: the lock
            seen["rendered again"] = True
            Stimulus.objects.filter(pk=rendered_again).update(status=Stimulus.Status.RUNNING)
        if sql.startswith('SELECT "studyapp_stimulus"') and '"studyapp_system"."role"' in sql:
            seen["clips read"] = True
        return execute(sql, params, many, context)

    with connection.execute_wrapper(render_again_once_the_clips_are_read), pytest.raises(StudyFull):
        enrol(study, "second", {}, rng=random.Random(1))
    assert seen == {"clips read": True, "rendered again": True}
    assert Stimulus.objects.get(pk=rendered_again).status == Stimulus.Status.RUNNING
    assert stimulus_loads(study, an_hour_ago())[rendered_again] == 1
