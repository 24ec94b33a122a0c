"""The researcher's pages: the steps of a study with what is done, and the preview that records nothing."""

from __future__ import annotations

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse

from studyapp.models import Assignment, Participant, Question, Rating, Study
from studyapp.study_steps import study_steps
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def test_the_steps_say_what_is_done_and_what_is_missing():
    study = make_study(is_open=False, completion_code="")
    empty = Study.objects.create(owner=study.owner, title="Empty")
    assert [(s.name, s.done) for s in study_steps(empty)] == [
        ("Settings", True), ("Systems", False), ("Controls", False), ("Stimuli", False), ("Preview", False),
        ("Open", False)]
    assert [s.note for s in study_steps(empty)][1:4] == ["no model system yet", "none yet", "none generated"]
    steps = study_steps(study)
    assert [s.done for s in steps] == [True, True, True, True, True, False]
    assert steps[3].note == "12 of 12 clips finished" and "completion code" in steps[5].note  # why it cannot open
    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-systems", args=[study.pk])).content.decode()
    assert '<ol class="steps"' in page and 'aria-current="page"' in page and "12 of 12 clips finished" in page


def test_the_preview_shows_every_page_in_order_and_records_nothing():
    study = make_study(device_check=True, min_screen_width=300)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="l", text="First language?", choices="a\nb")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="c", text="Comments?", kind="text")
    client = Client()
    client.force_login(study.owner)
    names = []
    url = reverse("study-preview", args=[study.pk])
    while True:
        page = client.get(url).content.decode()
        assert "nothing\n    is recorded" in page and 'document.addEventListener("submit"' in page
        names.append(page.split("Preview ")[1].split(":")[0])
        if "Next page" not in page:
            break
        url = page.split('<a href="')[1].split('"')[0]
    assert names == ["1 of 7 (device check)", "2 of 7 (consent)", "3 of 7 (screening)", "4 of 7 (instructions)",
                     "5 of 7 (a clip to rate)", "6 of 7 (closing questions)", "7 of 7 (completion)"]
    assert "C0MPL3TE" in page
    assert (Participant.objects.count(), Assignment.objects.count(), Rating.objects.count()) == (0, 0, 0)
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert stranger.get(reverse("study-preview", args=[study.pk])).status_code == 404
