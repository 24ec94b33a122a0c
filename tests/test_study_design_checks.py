"""Attention checks per design: thresholds on side-by-side pages, BAD preferred on pairwise
pages, and instructed checks (counted, never exported, ending a session after N failures)."""

from __future__ import annotations

import io
from datetime import timedelta

import pytest
from django.test import Client
from django.utils import timezone

from analysis.ratings.schema import read_ratings
from studyapp.designs.multi_clip import page_loads
from tests.study_fixtures import current_clip, current_page
from studyapp.designs.rules import StudyRules
from studyapp.models import Participant, Rating, System
from studyapp.researchers.results.export import ratings_csv
from tests.study_fixtures import make_study
from tests.test_study_designs import PAIRWISE, SIDE_BY_SIDE, compare, page_html, rate_page, through_practice
from tests.test_study_participant import post, rate_current
from tests.test_study_participant import through_practice as through_single_practice

pytestmark = pytest.mark.django_db


def answer_side_by_side_until(client, study, participant, role, value) -> None:
    """Answer pages (everything at 50) until one shows a clip of ``role``; give that clip ``value``."""
    while not any(a.stimulus.system.role == role for a in current_page(participant)):
        rate_page(client, study, participant)
    rate_page(client, study, participant, lambda a: value if a.stimulus.system.role == role else 50)


@pytest.mark.parametrize("role, value, excluded", [
    (System.Role.NATURAL, 24, True), (System.Role.NATURAL, 25, False),
    (System.Role.BAD, 75, True), (System.Role.BAD, 74, False),
])
def test_side_by_side_pages_flag_nat_below_25_and_bad_at_75_or_above(role, value, excluded):
    study = make_study(**SIDE_BY_SIDE, bad_checks=2)
    client = Client()
    participant = through_practice(client, study)
    answer_side_by_side_until(client, study, participant, role, value)
    participant.refresh_from_db()
    assert participant.excluded is excluded
    if excluded:
        assert participant.exclusion_reason == ("rated a NAT clip low" if role == System.Role.NATURAL
                                                else "rated a BAD clip high")


@pytest.mark.parametrize("prefer, excluded", [(System.Role.BAD, True), (System.Role.NATURAL, False), (None, False)])
def test_preferring_bad_on_a_pairwise_check_page_flags_the_participant(prefer, excluded):
    study = make_study(**PAIRWISE, bad_checks=1)
    client = Client()
    participant = through_practice(client, study)
    while not any(a.stimulus.system.role == System.Role.BAD for a in current_page(participant)):
        compare(client, study, participant, "none")
    page = current_page(participant)
    answer = next((side for a, side in zip(page, ("left", "right")) if a.stimulus.system.role == prefer), "none")
    assert compare(client, study, participant, answer).status_code == 302
    participant.refresh_from_db()
    assert participant.excluded is excluded
    assert participant.exclusion_reason == ("preferred a BAD clip" if excluded else "")


def test_an_instructed_check_on_a_single_clip_counts_failures_and_is_never_exported():
    study = make_study(controls=3, clips_per_participant=4, bad_checks=0, natural_checks=0, instructed_checks=1)
    client = Client()
    participant = through_single_practice(client, study)
    checks = participant.assignments.exclude(expected="")
    assert checks.count() == 1 and checks.get().position > 0  # never the first page
    while not current_clip(participant).expected:
        rate_current(client, study, participant, 3)
    expected = int(current_clip(participant).expected)
    assert f"please answer {expected}." in page_html(client, study)
    wrong = study.scale_min if expected != study.scale_min else study.scale_max
    rate_current(client, study, participant, wrong)
    participant.refresh_from_db()
    assert participant.failed_checks == 1 and participant.stopped_at is None and not participant.excluded
    while current_clip(participant):
        rate_current(client, study, participant, 3)
    assert "C0MPL3TE" in page_html(client, study)  # one failure, no limit set: the session goes on
    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert len(table) == Rating.objects.count() - 1 == 3  # the check is one of the 4 clips


@pytest.mark.parametrize("settings, answer_well", [
    (SIDE_BY_SIDE, lambda page: (lambda a: 100 if a.expected == "max" else 30)),
    (PAIRWISE, lambda page: page[0].expected),
])
def test_instructed_checks_of_side_by_side_and_pairwise_pass_when_followed(settings, answer_well):
    study = make_study(**{**settings, "pages_per_participant": 4, "bad_checks": 0, "instructed_checks": 2,
                          "stop_after_failed_checks": 1})
    client = Client()
    participant = through_practice(client, study)
    while current_page(participant):
        page = current_page(participant)
        html = page_html(client, study)
        if page[0].expected:
            assert "Attention check" in html
            good = answer_well(page)
            response = (rate_page(client, study, participant, good) if study.design == "side-by-side"
                        else compare(client, study, participant, good))
        else:
            assert "Attention check" not in html
            response = (rate_page(client, study, participant) if study.design == "side-by-side"
                        else compare(client, study, participant, "none"))
        assert response.status_code == 302
    participant.refresh_from_db()
    assert participant.failed_checks == 0 and "C0MPL3TE" in page_html(client, study)


def test_a_session_ends_politely_after_the_studys_number_of_failed_instructed_checks():
    study = make_study(**PAIRWISE, bad_checks=0, instructed_checks=3, stop_after_failed_checks=2, controls=4)
    client = Client()
    participant = through_practice(client, study)
    failed = 0
    while failed < 2:
        page = current_page(participant)
        if page[0].expected:
            compare(client, study, participant, "right" if page[0].expected == "left" else "left")
            failed += 1
        else:
            compare(client, study, participant, "none")
    participant.refresh_from_db()
    assert participant.failed_checks == 2 and participant.stopped_at and participant.finished_at
    html = page_html(client, study)
    assert "Thank you for your time" in html and "C0MPL3TE" not in html
    assert post(client, study, "rate", page="0" * 32, answer="left").status_code == 409
    # Their unanswered pages no longer hold places: only the pages they answered count.
    answered = participant.assignments.filter(rating__isnull=False, expected="").values("page").distinct().count()
    assert participant.assignments.filter(rating__isnull=True).exists()
    assert sum(page_loads(study, timezone.now() - timedelta(hours=1)).values()) == answered


@pytest.mark.parametrize("settings", [SIDE_BY_SIDE, PAIRWISE])
def test_the_analysis_recomputes_the_apps_flags_of_each_design_and_agrees(settings):
    from analysis.ratings.exclusions import apply_exclusions, exclusion_notes

    study = make_study(**{**settings, "bad_checks": 1, "instructed_checks": 1})
    side_by_side = study.design == "side-by-side"
    for pid, careful, hasty in (("careful", True, False), ("careless", False, False), ("hasty", True, True)):
        client = Client()
        participant = through_practice(client, study, pid)
        first = True
        while page := current_page(participant):
            early = {"ended_s-1": "", "ended_s-2": ""} if hasty and first else {}
            if side_by_side:
                low = not careful and any(a.stimulus.system.role == System.Role.NATURAL for a in page)
                rate_page(client, study, participant, lambda a: 10 if low and a.stimulus.system.role ==
                          System.Role.NATURAL else 100 if a.expected == "max" else 60, **early)
            else:
                roles = [a.stimulus.system.role for a in page]
                prefer_bad = not careful and System.Role.BAD in roles and not page[0].expected
                answer = page[0].expected or ("left" if (roles[0] == System.Role.BAD) == prefer_bad else "right")
                compare(client, study, participant, answer, **early)
            first = False
    flags = {p.platform_id: p.excluded for p in Participant.objects.filter(study=study)}
    assert flags == {"careful": False, "careless": True, "hasty": False}
    flagged = apply_exclusions(read_ratings(io.StringIO(ratings_csv(study).decode())), StudyRules.of(study).exclusion)
    assert not [note for note in exclusion_notes(flagged, StudyRules.of(study).exclusion) if "disagrees" in note]
    assert flagged["discarded_early"].any() and flagged["excluded_participant"].any()


@pytest.mark.parametrize("settings, heading", [
    ({"clips_per_participant": 8}, "Clip 1 of 8"),
    ({**SIDE_BY_SIDE, "pages_per_participant": 8}, "Page 1 of 8"),
    ({**PAIRWISE, "pages_per_participant": 8}, "Page 1 of 8"),
], ids=["single", "side-by-side", "pairwise"])
def test_instructed_checks_are_counted_among_the_pages_a_participant_answers(settings, heading):
    study = make_study(**settings, controls=8, instructed_checks=1, training_clips=0)
    client = Client()
    participant = through_practice(client, study)
    pages = participant.assignments.values_list("page", flat=True).distinct().count()
    instructed = participant.assignments.exclude(expected="").values_list("page", flat=True).distinct().count()
    assert (pages, instructed) == (8, 1)
    assert heading in page_html(client, study)

