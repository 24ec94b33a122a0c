"""Ids a form or an address takes: anything but an id of the study's own rows is a 4xx
with a message, never a 500, and changes nothing."""

from __future__ import annotations

import html

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Question, System
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db

HOSTILE_IDS = ["abc", "", "1.5", "-1", "9" * 400, "9" * 5000, "0x10", "1 OR 1=1", "None", "[1]"]


@pytest.mark.parametrize("question", HOSTILE_IDS)
def test_removing_a_question_by_a_hostile_id_is_a_400_and_removes_nothing(question):
    study = make_study()
    other = make_study(owner_name="other")
    kept = [Question.objects.create(study=s, part=Question.Part.AFTER, name="comments", text="Any comments?",
                                    kind=Question.Kind.TEXT) for s in (study, other)]
    client = Client()
    client.force_login(study.owner)
    url = reverse("study-questions", args=[study.pk])

    response = client.post(url, {"action": "remove", "question": question})

    assert response.status_code == 400
    assert "Nothing removed: " in html.unescape(response.content.decode())
    assert Question.objects.count() == 2
    # Another study's question is no question of this one either.
    assert client.post(url, {"action": "remove", "question": kept[1].pk}).status_code == 400
    assert client.post(url, {"action": "remove", "question": kept[0].pk}).status_code == 302
    assert list(Question.objects.all()) == [kept[1]]


@pytest.mark.parametrize("number", ["9" * 400, str(2**63), str(2**31)])
def test_addresses_with_ids_past_any_integer_are_404(number):
    study = make_study(controls=1)
    client = Client()
    client.force_login(study.owner)
    moglow = study.systems.get(name="MoGlow")
    for method, url in [("get", f"/studies/{number}/"), ("get", f"/studies/{study.pk}/systems/{number}/edit/"),
                        ("post", f"/studies/{study.pk}/systems/{number}/remove/"),
                        ("post", f"/studies/{study.pk}/stimuli/{number}/retry/"),
                        ("get", f"/studies/{number}/controls.zip"), ("get", f"/studies/{number}/monitor/")]:
        assert getattr(client, method)(url).status_code == 404, url
    assert client.get(f"/studies/{study.pk}/preview/{number}/").status_code in (302, 404)
    assert System.objects.filter(pk=moglow.pk).exists()


@pytest.mark.parametrize("slot", ["²", "٣", "-1", "1" * 19, "9" * 5000])
def test_a_side_by_side_field_whose_slot_is_no_ascii_number_is_ignored_as_any_unknown_field(slot):
    """"value-²" passed the slot check (isdigit) and failed int(), as did 5000 digits (past
    int()'s limit): a 500. Like any field the form does not have, such a field is now
    ignored, and the page's answer is stored on its own slots. (Sent URL-encoded: in a
    multipart body a name of 5000 characters is already refused with its headers.)"""
    from urllib.parse import urlencode

    from tests.test_study_designs import SIDE_BY_SIDE, page_html, page_token, through_practice, watched
    from tests.test_study_participant import make_shown_long_ago

    study = make_study(**SIDE_BY_SIDE)
    client = Client()
    participant = through_practice(client, study)
    token = page_token(page_html(client, study))
    make_shown_long_ago(participant)
    slots = sorted(participant.assignments.filter(page=0).values_list("slot", flat=True))

    form = {"page": token, **{f"value-{s}": 50 for s in slots}, f"value-{slot}": 70, **watched(slots),
            **{f"moved-{s}": "1" for s in slots}}
    response = client.post(reverse("participant-rate", args=[study.key]), urlencode(form),
                           content_type="application/x-www-form-urlencoded")

    assert response.status_code == 302
    rated = participant.assignments.filter(rating__isnull=False).order_by("slot")
    assert [(a.slot, a.rating.value) for a in rated] == [(s, 50) for s in slots]


def test_a_form_field_name_past_djangos_multipart_limit_is_a_400_not_a_500():
    study = make_study()
    client = Client()
    client.force_login(study.owner)
    for url in (reverse("study-questions", args=[study.pk]), f"/p/{study.key}/consent/"):
        response = client.post(url, {"x" * 10_000: "1"})  # multipart: the name goes in the part's headers
        assert response.status_code == 400, url
        assert "Bad request" in response.content.decode()
    assert not Question.objects.exists()
