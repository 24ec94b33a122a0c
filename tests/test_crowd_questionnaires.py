"""Questions before the ratings (screening) and after them, and the device check before consent."""

from __future__ import annotations

import csv
import io

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Question, Study
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, post, rate_current

pytestmark = pytest.mark.django_db


def add_questions(study: Study) -> None:
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language", text="Is English your first language?",
                            choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments?",
                            kind=Question.Kind.TEXT, required=False)


def page(client: Client, study: Study) -> str:
    return client.get(reverse("participant-page", args=[study.key])).content.decode()


def test_a_screening_answer_that_does_not_match_ends_the_study_politely_and_frees_the_clips():
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0)
    add_questions(study)
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    assert "Is English your first language?" in page(client, study)
    missing = post(client, study, "screening", **{"q-language": "yes"})
    assert missing.status_code == 400 and "How old are you?" in missing.content.decode()
    assert post(client, study, "screening", **{"q-language": "maybe", "q-age": "30"}).status_code == 400
    assert post(client, study, "screening", **{"q-language": "no", "q-age": "30"}).status_code == 302
    participant = Participant.objects.get()
    assert participant.screened_out_at is not None and participant.answers == {"language": "no", "age": 30}
    assert participant.assignments.count() == 0  # the reserved clips went back
    text = page(client, study)
    assert "ends here for you" in text and "return it on your platform" in text and "C0MPL3TE" not in text
    assert post(client, study, "instructions").status_code == 409


def test_matching_answers_go_on_and_every_answer_reaches_the_participant_csv():
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0)
    add_questions(study)
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    post(client, study, "screening", **{"q-language": "yes", "q-age": "41"})
    assert "Instructions" in page(client, study)
    post(client, study, "instructions")
    participant = Participant.objects.get()
    for index in range(len(participant.training)):
        post(client, study, "practice", index=index)
    for _ in range(3):
        rate_current(client, study, participant, 4)
    closing = page(client, study)
    assert "Any comments?" in closing and "C0MPL3TE" not in closing  # the code comes after the questions
    post(client, study, "survey", **{"q-comments": "=cmd|' /C calc'!A0"})
    assert "C0MPL3TE" in page(client, study)

    researcher = Client()
    researcher.force_login(study.owner)
    table = list(csv.DictReader(io.StringIO(
        researcher.get(reverse("study-participants-csv", args=[study.pk])).content.decode())))
    assert [(r["answer_language"], r["answer_age"], r["answer_comments"]) for r in table] == [
        ("yes", "41", "'=cmd|' /C calc'!A0")]
    assert "41" in researcher.get(reverse("study-participants", args=[study.pk])).content.decode()


def test_without_questions_consent_leads_to_the_instructions():
    study = make_study()
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    assert "Instructions" in page(client, study)


def test_the_device_check_comes_before_consent_plays_no_stimulus_and_refuses_a_small_screen():
    study = make_study(device_check=True, min_screen_width=600, min_screen_height=400)
    client = Client()
    first = enter(client, study).content.decode()
    assert "Checking your device" in first and "at least 600 × 400 pixels" in first
    # Before consent: a neutral clip (the synthetic walker), no stimulus of this or any study.
    assert 'src="/static/studyapp/device-check.mp4"' in first and "/media/" not in first
    assert all(stimulus.video_url not in first for stimulus in study.stimuli.all())
    assert post(client, study, "consent", agree="yes").status_code == 409  # not before the check
    small = post(client, study, "device", width=390, height=844)
    assert small.status_code == 409 and "at least 600 × 400" in small.content.decode()
    assert post(client, study, "device", width="wide", height=800).status_code == 400
    assert post(client, study, "device", width=1280, height=800).status_code == 302
    participant = Participant.objects.get()
    assert participant.device_checked_at is not None and "Consent" in page(client, study)


def test_the_researcher_adds_and_removes_questions_until_someone_starts():
    study = make_study()
    client = Client()
    client.force_login(study.owner)
    url = reverse("study-questions", args=[study.pk])
    form = {"action": "add", "part": "before", "name": "language", "text": "First language English?",
            "kind": "choice", "choices": "yes\nno", "accepted": "yes", "required": "on"}
    assert client.post(url, form).status_code == 302
    assert client.post(url, form).status_code == 400  # the same name twice
    bad = client.post(url, {**form, "name": "other", "choices": "yes", "accepted": ""})
    assert bad.status_code == 400 and "at least two choices" in bad.content.decode()
    unknown = client.post(url, {**form, "name": "other", "accepted": "perhaps"})
    assert unknown.status_code == 400 and "not among the choices: perhaps" in unknown.content.decode()
    after = client.post(url, {**form, "name": "other", "part": "after"})
    assert after.status_code == 400 and "only questions before the ratings screen" in after.content.decode()
    question = Question.objects.get()
    assert client.post(url, {"action": "remove", "question": question.pk}).status_code == 302
    assert not Question.objects.exists()
    client.post(url, form)
    enter(Client(), study)
    assert client.post(url, {**form, "name": "late"}).status_code == 302
    assert list(Question.objects.values_list("name", flat=True)) == ["language"]
    assert "the questions are fixed" in client.get(url).content.decode()


def test_the_device_checks_clip_is_the_whole_synthetic_walker_as_the_renderer_draws_it(tmp_path):
    from generation.render.synthetic import walking_in_a_circle
    from generation.render.video_check import check_rendered_video
    from studyapp.participants.device_clip import CLIP_PATH, FPS, SECONDS, SIZE, render_device_clip

    walker = walking_in_a_circle(SECONDS, FPS)
    shipped = check_rendered_video(CLIP_PATH, walker)  # the static file decodes to its last frame
    again = check_rendered_video(render_device_clip(tmp_path / "again.mp4"), walker)
    assert shipped.frames == again.frames == round(SECONDS * FPS) and shipped.size == again.size == SIZE
