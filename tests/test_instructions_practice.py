"""The instructions promise practice clips only to a participant who has them."""

from __future__ import annotations

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, post

PROMISE = "First come a few practice clips"

pytestmark = pytest.mark.django_db


def instructions(client: Client, study, pid: str = "pid-1") -> tuple[str, Participant]:
    enter(client, study, pid)
    post(client, study, "consent", agree="yes")
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert "<h1>Instructions</h1>" in page
    return page, Participant.objects.get(study=study, platform_id=pid)


def test_a_participant_who_rates_every_clip_is_promised_no_practice():
    # One control: four clips, all of them on the participant's pages, none left to practise on.
    study = make_study(controls=1, clips_per_participant=4, training_clips=2, ratings_per_stimulus=10)
    page, participant = instructions(Client(), study)
    assert participant.training == [] and PROMISE not in page


def test_a_participant_with_practice_clips_is_told_of_them():
    study = make_study(controls=3, clips_per_participant=4, training_clips=2, ratings_per_stimulus=10)
    page, participant = instructions(Client(), study)
    assert len(participant.training) == 2 and PROMISE in page
