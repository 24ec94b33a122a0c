"""The participant's pages beyond the rating itself: plain pages of the study's own for
every error, the next clip fetched ahead, the completion code's copy button."""

from __future__ import annotations

import logging
import re

import pytest
from django.test import Client
from django.urls import reverse

from tests.study_fixtures import current_clip
from studyapp.models import Participant, Stimulus
from studyapp.participants import path as participant_path
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, make_shown_long_ago, post, rate_current, through_practice

pytestmark = pytest.mark.django_db

DEBUG_MARKS = ("Traceback", "technical", "Django", "DEBUG = True", "Using the URLconf")


def plain(response, status: int, text: str) -> None:
    page = response.content.decode()
    assert response.status_code == status and text in page
    assert not any(mark in page for mark in DEBUG_MARKS), page[:500]
    assert 'class="participant"' in page  # the participants' own page


def test_unknown_links_closed_studies_and_server_errors_get_plain_pages_even_under_debug(settings, monkeypatch, caplog):
    settings.DEBUG = True
    study = make_study(is_open=False)
    client = Client()
    plain(client.get("/p/no-such-study/", {"PROLIFIC_PID": "x"}), 404, "There is no study at this address")
    plain(client.get("/p/no-such-study/now/"), 404, "There is no study at this address")
    plain(client.get(f"/p/{study.key}/", {"PROLIFIC_PID": "x"}), 404, "This study is closed")
    plain(client.get(f"/p/{study.key}/no/such/page/"), 404, "There is no such page in this study")
    study.is_open = True
    study.save()
    enter(client, study)

    def broken(participant):
        raise RuntimeError("the database went away")

    monkeypatch.setattr(participant_path, "renew_reservations", broken)
    with caplog.at_level(logging.ERROR, logger="studyapp.participants.views"):
        plain(client.get(reverse("participant-page", args=[study.key])), 500, "Something went wrong")
    assert "the database went away" in caplog.text  # the traceback goes to the log, not to the participant


def prefetched(client: Client, study) -> str | None:
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    match = re.search(r'<video data-upcoming src="([^"]+)"', page)
    return match.group(1) if match else None


def test_each_clip_page_fetches_the_next_clip_ahead():
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0, training_clips=2)
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    participant = Participant.objects.get(study=study)
    second_practice = Stimulus.objects.get(pk=participant.training[1])
    assert prefetched(client, study) == second_practice.video_url
    post(client, study, "practice", index=0)
    post(client, study, "practice", index=1)
    order = list(participant.assignments.order_by("position").select_related("stimulus"))
    for index, assignment in enumerate(order):
        expected = order[index + 1].stimulus.video_url if index + 1 < len(order) else None
        assert prefetched(client, study) == expected
        rate_current(client, study, participant, 3)
    assert current_clip(participant) is None


def test_the_completion_page_offers_to_copy_the_code():
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0)
    client = Client()
    participant = through_practice(client, study)
    for _ in range(3):
        make_shown_long_ago(participant)
        rate_current(client, study, participant, 3)
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert 'id="copy-code"' in page and 'writeText("C0MPL3TE")' in page


def test_a_form_without_its_csrf_token_gets_a_plain_page_that_leads_back(settings):
    settings.DEBUG = True
    study = make_study()
    client = Client(enforce_csrf_checks=True)
    enter(client, study)
    response = post(client, study, "consent", agree="yes")
    plain(response, 403, "This page had expired")
    assert f'href="{reverse("participant-page", args=[study.key])}"' in response.content.decode()
    assert Participant.objects.get().consented_at is None
