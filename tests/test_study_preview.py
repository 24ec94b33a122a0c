"""The researcher's preview is the participant's path: every design's own pages, practice
included, and whatever step the path has."""

from __future__ import annotations

import re

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Assignment, Participant, Rating, Stimulus
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import make_study
from tests.test_study_designs import PAIRWISE, SIDE_BY_SIDE

pytestmark = pytest.mark.django_db


def preview(study) -> dict[str, str]:
    """The preview's pages, page name -> HTML, in order."""
    client = Client()
    client.force_login(study.owner)
    pages, url = {}, reverse("study-preview", args=[study.pk])
    while url:
        html = client.get(url).content.decode()
        pages[html.split("Preview ")[1].split("(")[1].split(")")[0]] = html
        url = html.split('<a href="')[1].split('"')[0] if "Next page" in html else ""
    return pages


# Each design's study, what only its rating page has, and how many clips a page shows.
DESIGNS = {
    "single": (make_study, {}, ['name="value"'], 1),
    "side-by-side": (make_study, SIDE_BY_SIDE, ['type="range"'], 2),
    "pairwise": (make_study, PAIRWISE, ['name="answer"'], 2),
    # which clip follows the path drawn on the floor, and how clearly (five levels)
    "appropriateness": (make_appropriateness_study, {}, ['name="answer"', 'name="strength"', "orange band on the floor"], 2),
}


@pytest.mark.parametrize("design", list(DESIGNS))
def test_the_preview_shows_the_designs_own_rating_and_practice_pages(design):
    make, settings, answer, clips = DESIGNS[design]
    study = make(**settings, training_clips=2)
    pages = preview(study)
    assert list(pages) == ["consent", "instructions", "practice", "a page to rate", "completion"]
    for name, heading in (("practice", "Practice"), ("a page to rate", "1 of")):
        html = pages[name]
        assert all(marker in html for marker in answer) and heading in html and html.count("<video") >= clips, name
    assert "(not recorded)" in pages["practice"]
    assert (Participant.objects.count(), Assignment.objects.count(), Rating.objects.count()) == (0, 0, 0)


def test_the_appropriateness_preview_pairs_one_systems_matched_and_mismatched_clips():
    study = make_appropriateness_study(training_clips=2)
    pages = preview(study)
    by_url = {s.video_url: s for s in Stimulus.objects.filter(study=study)}
    for name in ("practice", "a page to rate"):
        clips = [by_url[url] for url in re.findall(r'<video data-slot="\d" src="([^"]+)"', pages[name])]
        matched = [c for c in clips if c.shown_control_id is None]
        mismatched = [c for c in clips if c.shown_control_id is not None]
        assert len(matched) == len(mismatched) == 1 and len({c.system_id for c in clips}) == 1, name
        assert mismatched[0].shown_control_id == matched[0].control_id != mismatched[0].control_id, name
