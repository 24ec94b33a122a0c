"""The researcher's preview is the participant's path: every design's own pages, practice
included, and whatever step the path has."""

from __future__ import annotations

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Assignment, Participant, Rating
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


@pytest.mark.parametrize("settings, answer", [({}, 'name="value"'), (SIDE_BY_SIDE, 'type="range"'),
                                              (PAIRWISE, 'name="answer"')], ids=["single", "side-by-side", "pairwise"])
def test_the_preview_shows_the_designs_own_rating_and_practice_pages(settings, answer):
    study = make_study(**settings, training_clips=2)
    pages = preview(study)
    assert list(pages) == ["consent", "instructions", "practice", "a page to rate", "completion"]
    clips = 1 if not settings else 2  # one clip, or a page of several
    for name, heading in (("practice", "Practice"), ("a page to rate", "1 of")):
        html = pages[name]
        assert answer in html and heading in html and html.count("<video") >= clips, name
    assert "(not recorded)" in pages["practice"]
    assert (Participant.objects.count(), Assignment.objects.count(), Rating.objects.count()) == (0, 0, 0)
