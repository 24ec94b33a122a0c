"""Adaptive pairing as a pairwise study's setting: a new participant's pairs are planned
from the fit of the votes stored so far (`analysis.rankings.pairing.plan_pairs`), sides balanced,
and evenly as without the setting while there are too few votes."""

from __future__ import annotations

import random
from collections import Counter

import numpy as np
import pytest
from django.utils import timezone

from analysis.rankings.pairing import plan_pairs
from studyapp.designs.pairwise_pages import stored_pages
from studyapp.models import Assignment, Participant, Rating, Stimulus
from studyapp.participants.assignment import enrol
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db

SYSTEMS = ["MoGlow", "NAT", "RNN"]
# NAT against MoGlow often (NAT clearly better), RNN hardly: what the ranking is unsure of is RNN.
SKEWED = [("NAT", "MoGlow", "left", 2)] * 12 + [("MoGlow", "NAT", "right", 2)] * 12 + [
    ("NAT", "RNN", "left", 1), ("RNN", "NAT", "none", None), ("MoGlow", "RNN", "left", 1), ("RNN", "MoGlow", "none", None)]
NEW_PARTICIPANTS, PAGES = 5, 6


def pairwise_study(adaptive: bool):
    return make_study(design="pairwise", controls=12, pages_per_participant=PAGES, bad_checks=0, training_clips=0,
                      ratings_per_stimulus=50, adaptive_pairing=adaptive)


def store_votes(study, votes: list[tuple]) -> None:
    """One finished participant per vote, who answered a page of the two systems' clips."""
    clip = {(s.system.name, s.control.name): s for s in Stimulus.objects.filter(study=study).select_related(
        "system", "control")}
    for n, (left, right, answer, strength) in enumerate(votes):
        person = Participant.objects.create(study=study, platform_id=f"past-{n}", finished_at=timezone.now())
        control = f"control-{n % 12}"
        for slot, system in ((Assignment.LEFT, left), (Assignment.RIGHT, right)):
            assignment = Assignment.objects.create(participant=person, stimulus=clip[system, control],
                                                   position=slot - 1, page=0, slot=slot)
            Rating.objects.create(assignment=assignment, answer=answer, strength=strength)


def planned_pages(study) -> list[tuple[str, str]]:
    """(left, right) systems of each page handed to the new participants."""
    pages: dict[tuple[int, int], dict[int, str]] = {}
    for a in Assignment.objects.filter(participant__study=study, participant__platform_id__startswith="new-").order_by(
            "participant_id", "page", "slot"):
        pages.setdefault((a.participant_id, a.page), {})[a.slot] = a.stimulus.system.name
    return [(page[Assignment.LEFT], page[Assignment.RIGHT]) for page in pages.values()]


def enrol_new(study) -> list[tuple[str, str]]:
    for n in range(NEW_PARTICIPANTS):
        enrol(study, f"new-{n}", {}, rng=random.Random(n))
    return planned_pages(study)


def pair_counts(pages) -> Counter:
    return Counter(frozenset(page) for page in pages)


def test_adaptive_pages_go_where_the_fit_of_the_stored_votes_says_with_sides_balanced():
    study = pairwise_study(adaptive=True)
    store_votes(study, SKEWED)
    pages = enrol_new(study)
    assert len(pages) == NEW_PARTICIPANTS * PAGES
    # What the criterion alone plans (no exploration) from the same votes, page after page.
    stored = stored_pages(study)
    assert stored["vote"].sum() == len(SKEWED) and stored["held"].sum() == len(pages)  # the new ones hold theirs
    reference = pair_counts(plan_pairs(stored[stored["vote"]], SYSTEMS, len(pages), np.random.default_rng(0),
                                       exploration=0.0))
    counts = pair_counts(pages)
    for pair in reference | counts:  # exploration draws a tenth of the pages uniformly
        assert abs(counts[pair] - reference[pair]) <= 4, (pair, counts, reference)
    # RNN, hardly compared, against the anchor: most pages (planned evenly, at most half of them)
    assert counts[frozenset(("NAT", "RNN"))] >= 2 * len(pages) / 3
    # Sides balanced per pair of systems over the study, the stored pages included.
    sides = Counter(pages) + Counter((left, right) for left, right, *_ in SKEWED)
    for left, right in list(sides):
        assert abs(sides[left, right] - sides[right, left]) <= 1, (left, right, sides)
    # Each pair of clips (a control) at most once per participant.
    for person in Participant.objects.filter(study=study, platform_id__startswith="new-"):
        controls = Counter((frozenset(a.stimulus.system.name for a in person.assignments.filter(page=page)),
                            person.assignments.filter(page=page).first().stimulus.control_id)
                           for page in range(PAGES))
        assert max(controls.values()) == 1


@pytest.mark.parametrize("adaptive, votes", [(False, SKEWED), (True, SKEWED[:2])],
                         ids=["setting off", "too few votes"])
def test_without_the_setting_or_with_too_few_votes_pages_are_planned_as_without_adaptive_pairing(
        adaptive, votes, monkeypatch):
    def no_fit(*args, **kwargs):
        raise AssertionError("the votes were fitted")

    monkeypatch.setattr("studyapp.designs.pairwise_pages.plan_pairs", no_fit)
    study = pairwise_study(adaptive)
    store_votes(study, votes)
    pages = enrol_new(study)
    assert len(pages) == NEW_PARTICIPANTS * PAGES and not any("BAD" in page for page in pages)
    if len(votes) == len(SKEWED):  # the least loaded pairs of clips first: NAT-MoGlow's carry two votes each
        assert frozenset(("NAT", "MoGlow")) not in pair_counts(pages[:4 * PAGES])
    else:  # nothing loaded yet: each participant sees each pair of systems as often
        for person in Participant.objects.filter(study=study, platform_id__startswith="new-"):
            mine = [tuple(a.stimulus.system.name for a in person.assignments.filter(page=page)) for page in range(PAGES)]
            assert sorted(pair_counts(mine).values()) == [2, 2, 2]
