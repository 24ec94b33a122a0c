"""Participants who leave before the end still leave with a code of their own: a
screened-out participant gets the study's screen-out code (Prolific pays it at its fixed
screen-out rate) instead of being told to return, one stopped by failed instructed checks
gets the stopped code, and a Prolific study that screens cannot open without the first."""

from __future__ import annotations

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Question, Study
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, post, rate_current, through_practice

pytestmark = pytest.mark.django_db

CODES = {"completion_code": "C0MPL3TE", "screen_out_code": "SCR33N", "stopped_code": "ST0PP3D"}


def page(client: Client, study: Study) -> str:
    return client.get(reverse("participant-page", args=[study.key])).content.decode()


def screen_out(client: Client, study: Study) -> str:
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    enter(client, study)
    post(client, study, "consent", agree="yes")
    assert post(client, study, "screening", **{"q-language": "no"}).status_code == 302
    return page(client, study)


def test_a_screened_out_prolific_participant_gets_the_screen_out_code_and_its_link_not_a_request_to_return():
    study = make_study(platform=Study.Platform.PROLIFIC, **CODES)
    html = screen_out(Client(), study)
    assert "ends here for you" in html and "SCR33N" in html
    assert 'href="https://app.prolific.com/submissions/complete?cc=SCR33N"' in html
    assert "C0MPL3TE" not in html and "ST0PP3D" not in html and "return it on your platform" not in html


def test_without_a_screen_out_code_the_screened_out_are_asked_to_return_as_before():
    study = make_study(platform=Study.Platform.PROLIFIC, completion_code="C0MPL3TE")
    html = screen_out(Client(), study)
    assert "return it on your platform" in html and "C0MPL3TE" not in html and "complete?cc=" not in html


def test_a_screened_out_mturk_worker_submits_the_screen_out_code_to_mturk():
    study = make_study(platform=Study.Platform.MTURK, **CODES)
    client = Client()
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    client.get(reverse("participant-enter", args=[study.key]), {
        "workerId": "W1", "assignmentId": "A1", "hitId": "H1", "turkSubmitTo": "https://workersandbox.mturk.com"})
    post(client, study, "consent", agree="yes")
    post(client, study, "screening", **{"q-language": "no"})
    html = page(client, study)
    assert 'action="https://workersandbox.mturk.com/mturk/externalSubmit"' in html
    assert 'name="completionCode" value="SCR33N"' in html and 'name="assignmentId" value="A1"' in html


def test_a_participant_stopped_by_failed_instructed_checks_gets_the_stopped_code():
    study = make_study(platform=Study.Platform.PROLIFIC, clips_per_participant=4, bad_checks=0, natural_checks=0,
                       instructed_checks=1, stop_after_failed_checks=1, **CODES)
    client = Client()
    participant = through_practice(client, study)
    while not Participant.objects.get(pk=participant.pk).stopped_at:
        asked = participant.assignments.filter(rating__isnull=True).order_by("position").first().expected
        rate_current(client, study, participant, (int(asked) % 5) + 1 if asked else 3)  # the wrong answer
    html = page(client, study)
    assert "Thank you for your time" in html and "ST0PP3D" in html
    assert 'href="https://app.prolific.com/submissions/complete?cc=ST0PP3D"' in html and "C0MPL3TE" not in html


def test_a_prolific_study_that_screens_opens_only_with_a_screen_out_code():
    study = make_study(platform=Study.Platform.PROLIFIC, is_open=False, completion_code="C0MPL3TE")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    client = Client()
    client.force_login(study.owner)
    refused = client.post(reverse("study-open", args=[study.pk]), {"open": "1"}, follow=True).content.decode()
    study.refresh_from_db()
    assert "set the screen-out code" in refused and not study.is_open
    Study.objects.filter(pk=study.pk).update(screen_out_code="SCR33N")
    client.post(reverse("study-open", args=[study.pk]), {"open": "1"})
    study.refresh_from_db()
    assert study.is_open


def test_the_settings_offer_both_codes_in_the_crowd_platform_section():
    study = make_study()
    client = Client()
    client.force_login(study.owner)
    html = client.get(reverse("study-edit", args=[study.pk])).content.decode()
    platform_section = html[html.index("<legend>Crowd platform</legend>"):]
    platform_section = platform_section[:platform_section.index("</fieldset>")]
    assert 'name="screen_out_code"' in platform_section and 'name="stopped_code"' in platform_section
