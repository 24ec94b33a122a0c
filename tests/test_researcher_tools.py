"""What a researcher expects to find on the study pages: removal that says what it deletes
before it does, a study deleted or duplicated, attention checks without their system warned
of, questions edited and reordered, the median completion time, every clip in one zip,
and the settings form showing what the chosen design reads, in words."""

from __future__ import annotations

import csv
import io
import zipfile
from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from studyapp.models import Assignment, Participant, Question, Rating, Stimulus, Study, System
from studyapp.participants.questionnaires import questions as questions_of
from studyapp.researchers.setup.forms import StudyForm
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def researcher(study: Study) -> Client:
    client = Client()
    client.force_login(study.owner)
    return client


def stranger() -> Client:
    client = Client()
    client.force_login(User.objects.create(username="stranger"))
    return client


@pytest.fixture
def videos(settings, tmp_path):
    """Every clip's video on disk (a few bytes each)."""
    settings.MEDIA_ROOT = tmp_path / "media"

    def write(study: Study) -> Study:
        for stimulus in study.stimuli.all():
            stimulus.video_path().parent.mkdir(parents=True, exist_ok=True)
            stimulus.video_path().write_bytes(f"video of {stimulus.content_key}".encode())
        return study
    return write


def test_removing_a_system_first_says_what_it_deletes_and_deletes_nothing_until_confirmed(videos):
    study = videos(make_study(controls=2))
    rnn = study.systems.get(name="RNN")
    url = reverse("study-remove", args=[study.pk, "systems", rnn.pk])
    client = researcher(study)
    assert f'href="{url}"' in client.get(reverse("study-systems", args=[study.pk])).content.decode()
    asked = client.get(url)
    assert asked.status_code == 200
    assert asked.context["deletes"] == ["the system RNN (model)", "its 2 clip(s): their videos"]
    assert "Remove RNN</button>" in asked.content.decode()
    assert study.systems.filter(name="RNN").exists() and rnn.stimuli.count() == 2
    assert stranger().get(url).status_code == 404
    client.post(url)
    assert not study.systems.filter(name="RNN").exists()


def test_a_study_is_deleted_with_everything_in_it_only_when_confirmed(videos):
    study = videos(make_study(controls=2))
    files = [s.video_path() for s in study.stimuli.all()]
    participant = Participant.objects.create(study=study, platform_id="p1")
    Rating.objects.create(assignment=Assignment.objects.create(participant=participant, stimulus=study.stimuli.first(),
                                                               position=0), value=3)
    url = reverse("study-delete", args=[study.pk])
    client = researcher(study)
    assert f'href="{url}"' in client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    asked = client.get(url)
    assert asked.context["deletes"] == [
        "the study “Naturalness of locomotion” and its settings", "its 4 system(s), 2 control(s) and 0 question(s)",
        "its 8 clip(s): their videos, and sampled motion no other study shares",
        "its 1 participant(s) with their 1 rating(s) and answers"]
    assert Study.objects.filter(pk=study.pk).exists()
    assert stranger().post(url).status_code == 404 and Study.objects.filter(pk=study.pk).exists()
    response = client.post(url, follow=True)
    assert "Deleted “Naturalness of locomotion” and its 8 clip(s)." in response.content.decode()
    assert not Study.objects.filter(pk=study.pk).exists() and not any(path.exists() for path in files)


def test_a_duplicated_study_has_the_settings_systems_controls_questions_and_clips_but_no_participants(videos):
    study = videos(make_study(controls=2, design="side-by-side", scale_min=0, scale_max=100, pages_per_participant=2,
                              camera={"azimuth": 10.0}))
    Question.objects.create(study=study, part=Question.Part.AFTER, name="age", text="Age?", kind="number")
    Participant.objects.create(study=study, platform_id="p1")
    response = researcher(study).post(reverse("study-duplicate", args=[study.pk]))
    copy = Study.objects.exclude(pk=study.pk).get()
    assert response.status_code == 302 and response["Location"] == reverse("study-edit", args=[copy.pk])
    assert (copy.title, copy.owner, copy.is_open, copy.participants.count()) == (
        "Copy of Naturalness of locomotion", study.owner, False, 0)
    assert (copy.design, copy.scale_max, copy.camera["azimuth"], copy.key != study.key) == ("side-by-side", 100, 10.0,
                                                                                            True)
    assert sorted(copy.systems.values_list("name", "role")) == sorted(study.systems.values_list("name", "role"))
    assert list(copy.questions.values_list("name", flat=True)) == ["age"]
    originals = {s.content_key: s for s in study.stimuli.all()}
    for clip in copy.stimuli.select_related("system", "control"):
        original = originals[clip.content_key]
        assert clip.token != original.token and clip.system.name == original.system.name
        assert clip.control.export_id == original.control.export_id
        assert clip.video_path().read_bytes() == original.video_path().read_bytes()
    assert copy.stimuli.count() == 8
    study.stimuli.first().video_path().unlink()  # the copy's videos are its own
    assert all(clip.video_path().exists() for clip in copy.stimuli.all())
    assert stranger().post(reverse("study-duplicate", args=[study.pk])).status_code == 404


def test_bad_checks_without_a_bad_system_warn_and_the_study_opens_only_once_they_are_seen():
    study = make_study(is_open=False, bad_checks=2)
    study.systems.filter(role=System.Role.BAD).delete()
    client = researcher(study)
    page = client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    assert 'id="open-warnings"' in page and "ask for 2 BAD check(s) per participant, but the study has no BAD" in page
    assert 'name="despite_warnings"' in page
    refused = client.post(reverse("study-open", args=[study.pk]), {"open": "1"}, follow=True)
    assert "Not opened: the settings ask for 2 BAD check(s)" in refused.content.decode()
    study.refresh_from_db()
    assert not study.is_open
    client.post(reverse("study-open", args=[study.pk]), {"open": "1", "despite_warnings": "1"})
    study.refresh_from_db()
    assert study.is_open
    with_bad = make_study(owner_name="other", is_open=False)
    assert 'id="open-warnings"' not in researcher(with_bad).get(reverse("study-monitor", args=[with_bad.pk])).content.decode()


def test_questions_can_be_edited_and_reordered_and_participants_meet_them_in_that_order():
    study = make_study()
    for name in ("vision", "age", "country"):
        researcher(study).post(reverse("study-questions", args=[study.pk]), {
            "part": "before", "name": name, "text": f"{name}?", "kind": "text", "required": "on"})
    client = researcher(study)
    first, second, third = study.questions.all()
    assert [q.name for q in study.questions.all()] == ["vision", "age", "country"]
    move = reverse("study-question-move", args=[study.pk, third.pk])
    client.post(move, {"direction": "up"})
    client.post(move, {"direction": "up"})
    assert [q.name for q in questions_of(study, Question.Part.BEFORE)] == ["country", "vision", "age"]
    at_top = client.post(move, {"direction": "up"}, follow=True)
    assert "is first of its part already" in at_top.content.decode()
    edit = reverse("study-question-edit", args=[study.pk, first.pk])
    assert client.post(edit, {"part": "before", "name": "age", "text": "x", "kind": "text"}).status_code == 400
    client.post(edit, {"part": "after", "name": "sight", "text": "How is your sight?", "kind": "choice",
                       "choices": "good\npoor", "required": "on"})
    first.refresh_from_db()
    assert (first.name, first.part, first.choice_list) == ("sight", "after", ["good", "poor"])
    assert [q.name for q in questions_of(study, Question.Part.BEFORE)] == ["country", "age"]
    Participant.objects.create(study=study, platform_id="p1")
    client.post(edit, {"part": "after", "name": "late", "text": "Too late?", "kind": "text"})
    client.post(move, {"direction": "down"})
    first.refresh_from_db()
    assert first.name == "sight" and [q.name for q in questions_of(study, Question.Part.BEFORE)] == ["country", "age"]


def test_the_participant_list_gives_the_median_completion_time_of_those_who_completed():
    study = make_study()
    now = timezone.now()
    for i, minutes in enumerate([10, 14, 30, 12]):
        Participant.objects.create(study=study, platform_id=f"p{i}")
        Participant.objects.filter(study=study, platform_id=f"p{i}").update(
            started_at=now - timedelta(minutes=minutes), finished_at=now)
    Participant.objects.create(study=study, platform_id="stopped", finished_at=now, stopped_at=now)
    Participant.objects.create(study=study, platform_id="screened", finished_at=now, screened_out_at=now)
    Participant.objects.create(study=study, platform_id="still going")
    page = researcher(study).get(reverse("study-participants", args=[study.pk])).content.decode()
    assert "median of <strong>13.0 minutes</strong>" in page  # of 10, 12, 14 and 30
    assert "in 11.5–18.0 minutes;\n  4 completed" in page


def test_every_finished_clip_downloads_as_mp4_in_one_zip_with_an_index(videos):
    study = videos(make_study(controls=2))
    Stimulus.objects.filter(pk=study.stimuli.first().pk).update(status=Stimulus.Status.FAILED)
    url = reverse("study-stimuli-download", args=[study.pk])
    client = researcher(study)
    assert f'href="{url}"' in client.get(reverse("study-stimuli", args=[study.pk])).content.decode()
    response = client.get(url)
    assert response.status_code == 200 and response["Content-Type"] == "application/zip"
    with zipfile.ZipFile(io.BytesIO(b"".join(response.streaming_content))) as archive:
        names = archive.namelist()
        index = list(csv.DictReader(io.StringIO(archive.read(f"stimuli-study-{study.pk}/index.csv").decode())))
        done = study.stimuli.filter(status=Stimulus.Status.DONE)
        assert len(index) == done.count() == 7 and len(names) == 8
        for row in index:
            clip = done.get(token=row["stimulus"])
            assert (row["system"], row["control"]) == (clip.system.export_name, clip.control.name)
            assert archive.read(f"stimuli-study-{study.pk}/{row['file']}") == clip.video_path().read_bytes()
    assert "MoGlow/control-0.mp4" in {row["file"] for row in index} or "MoGlow/control-1.mp4" in {r["file"] for r in index}
    assert stranger().get(url).status_code == 404


@pytest.mark.parametrize(("design", "shown", "hidden"), [
    ("single", ["clips_per_participant", "natural_checks", "scale_min", "bad_threshold"],
     ["pages_per_participant", "abx", "preference_strengths", "adaptive_pairing"]),
    ("side-by-side", ["pages_per_participant", "scale_min", "bad_threshold"],
     ["clips_per_participant", "natural_checks", "abx", "adaptive_pairing"]),
    ("pairwise", ["pages_per_participant", "abx", "preference_strengths", "adaptive_pairing"],
     ["clips_per_participant", "scale_min", "label_max", "bad_threshold", "natural_threshold"]),
])
def test_the_settings_show_the_fields_the_chosen_design_reads(design, shown, hidden):
    study = make_study(design=design, **({"scale_min": 0, "scale_max": 100} if design == "side-by-side" else {}))
    page = researcher(study).get(reverse("study-edit", args=[study.pk])).content.decode()
    rows = {name: page[page.rindex('<div class="field', 0, page.index(f'name="{name}"')):page.index(f'name="{name}"')]
            for name in shown + hidden}
    assert all(" hidden>" not in rows[name] for name in shown)
    assert all(" hidden>" in rows[name] and "data-designs" in rows[name] for name in hidden)


def test_the_settings_are_labelled_in_words():
    form = StudyForm(instance=make_study())
    labels = {field.name: field.label for field in form}
    assert not [label for label in labels.values() if label in ("Abx", "Fov", "Near", "Redirect url", "Is open")]
    assert (labels["abx"], labels["camera_fov"], labels["camera_near"]) == (
        "Natural clip shown as a reference (ABX)", "Field of view (degrees, vertical)", "Nothing drawn nearer than (cm)")
