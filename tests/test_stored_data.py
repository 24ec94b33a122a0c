"""Data that can be in the database (written in the admin, by an older version, by hand)
never crashes a page: every researcher page and download, and the participant's page,
answer a study holding a broken row with a message naming the row and the field (4xx,
or the page without the broken part), never a 500; and the admin refuses to store such a
row in the first place.
"""

from __future__ import annotations

import html
from datetime import timedelta

import pytest
from django.contrib.auth.models import Permission, User
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from generation.control import preset_path
from generation.motion.dataset_options import DatasetOptions
from studyapp.models import Assignment, ControlSignal, Participant, Question, Rating, Stimulus, Study, System

pytestmark = [pytest.mark.django_db, pytest.mark.slow]

GOOD_CONTROL = preset_path("walk-straight", 20.0).to_dict()


def study_with_a_participant(owner: User) -> Study:
    """A single-design study with a checkpoint system, NAT and BAD, two synthetic controls,
    every clip done, and one participant who has rated two clips."""
    study = Study.objects.create(owner=owner, title="Gait", clips_per_participant=3, ratings_per_stimulus=3,
                                 training_clips=1, is_open=True, completion_code="DONE",
                                 platform=Study.Platform.PROLIFIC)
    metadata = {"dataset_options": DatasetOptions().to_dict(), "control": "path", "preset": "cpu", "step": 20,
                "parameters": 1000, "data_fingerprint": "0" * 64}
    systems = [System.objects.create(study=study, name="MoGlow", checkpoint="model.safetensors", kind="moglow",
                                     checkpoint_digest="1" * 64, metadata=metadata),
               System.objects.create(study=study, name="NAT", role=System.Role.NATURAL, kind="natural"),
               System.objects.create(study=study, name="BAD", role=System.Role.BAD, kind="video")]
    controls = [ControlSignal.objects.create(study=study, name=f"walk-{i}", origin=ControlSignal.Origin.SYNTHETIC,
                                             control={**GOOD_CONTROL, "name": f"walk-{i}"}, seconds=4.0)
                for i in range(2)]
    stimuli = [Stimulus.objects.create(study=study, system=system, control=control, status=Stimulus.Status.DONE,
                                       content_key=f"{system.name}-{control.name}", duration_s=4.0)
               for system in systems[:2] for control in controls]
    stimuli.append(Stimulus.objects.create(study=study, system=systems[2], status=Stimulus.Status.DONE,
                                           content_key="uploaded-video", duration_s=4.0))
    Question.objects.create(study=study, part=Question.Part.AFTER, name="age", text="Age?", kind=Question.Kind.NUMBER)
    now = timezone.now()
    participant = Participant.objects.create(study=study, platform_id="p1", platform_data={"SESSION_ID": "s1"},
                                             consented_at=now, screened_at=now,
                                             instructed_at=now, training=[stimuli[0].pk], training_done=1)
    for position, stimulus in enumerate(stimuli[:3]):
        assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=position,
                                               page=position, shown_at=now)
        if position < 2:
            Rating.objects.create(assignment=assignment, value=3 + position)
    return study


# What an admin form, an old version or a hand edit may have left, by (model, field).
BROKEN_ROWS = {
    "a control of only its type": (ControlSignal, {"control": {"type": "path"}}),
    "a control that is a list": (ControlSignal, {"control": [1, 2]}),
    "a control of an unknown type": (ControlSignal, {"control": {"type": "teleport", "fps": 20}}),
    "a control with a lead-in and no fps": (ControlSignal, {"control": {**GOOD_CONTROL, "lead_in": [[0, 0, 0]], "fps": None}}),
    "a control whose velocities are text": (ControlSignal, {"control": {**GOOD_CONTROL, "velocities": "fast"}}),
    "a system with neither checkpoint nor kind": (System, {"checkpoint": "", "kind": ""}),
    "a system of an unknown kind": (System, {"checkpoint": "", "kind": "telepathy"}),
    "a checkpoint system without its data options": (System, {"metadata": {"control": "path"}}),
    "a checkpoint system whose metadata is a list": (System, {"metadata": ["moglow"]}),
    "a checkpoint system with data options of text": (System, {"metadata": {"dataset_options": "bvh", "labels": 5}}),
    "a checkpoint system with unknown data options": (System, {"metadata": {"dataset_options": {"zoom": 2}}}),
    "a camera that is a list": (Study, {"camera": [35, 18]}),
    "a camera with an unknown setting": (Study, {"camera": {"zoom": 2}}),
    "a camera with text for a number": (Study, {"camera": {"distance": "far"}}),
    "answers that are a list": (Participant, {"answers": ["41"]}),
    "platform data that is text": (Participant, {"platform_data": "PROLIFIC"}),
    "practice clips that are an object": (Participant, {"training": {"0": 1}}),
    "practice clips of no stimulus": (Participant, {"training": ["abc", None]}),
    "an instructed check asking for a word": (Assignment, {"expected": "bogus"}),
    "a question of an unknown kind": (Question, {"kind": "slider"}),
    "a number question with no range": (Question, {"minimum": 500.0}),
    "a submitted system without its folder": (System, {"checkpoint": "", "kind": "submitted", "metadata": {}}),
    "a rating without its value": (Rating, {"value": None}),
    "a rating off the scale": (Rating, {"value": 999}),
    "a clip without its duration": (Stimulus, {"duration_s": None}),
}


def _break(study: Study, model, fields: dict) -> None:
    rows = {Study: Study.objects.filter(pk=study.pk), ControlSignal: study.controls.all(),
            System: study.systems.filter(name="MoGlow"), Participant: study.participants.all(),
            Assignment: Assignment.objects.filter(participant__study=study, position=2),
            Question: study.questions.all(), Rating: Rating.objects.filter(assignment__participant__study=study),
            Stimulus: study.stimuli.all()}[model]
    rows.update(**fields)


def researcher_pages(study: Study) -> list[tuple[str, str, dict]]:
    control, system = study.controls.first(), study.systems.get(name="MoGlow")
    edit = reverse("study-item-edit", args=[study.pk, "controls", control.pk])
    return [("get", url, {}) for url in (
        reverse("study-list"), reverse("study-edit", args=[study.pk]), reverse("study-systems", args=[study.pk]),
        reverse("study-controls", args=[study.pk]), reverse("study-controls-download", args=[study.pk]),
        reverse("study-controls-download", args=[study.pk]) + "?natural=1", reverse("study-stimuli", args=[study.pk]),
        reverse("study-progress", args=[study.pk]), edit,
        reverse("study-item-edit", args=[study.pk, "systems", system.pk]), reverse("study-monitor", args=[study.pk]),
        reverse("study-preview", args=[study.pk]), reverse("study-preview-page", args=[study.pk, 4]),
        reverse("study-questions", args=[study.pk]), reverse("study-participants", args=[study.pk]),
        reverse("study-participants-csv", args=[study.pk]), reverse("study-export", args=[study.pk]),
        reverse("study-motion-download", args=[study.pk]))] + [
        ("post", edit, {"name": "renamed"}),
        ("post", reverse("study-item-edit", args=[study.pk, "systems", system.pk]), {"name": "M2", "temperature": 0.5}),
        ("post", reverse("study-edit", args=[study.pk]), {"title": "Gait 2"}),
        ("post", reverse("study-report", args=[study.pk]), {}),
        ("post", reverse("study-open", args=[study.pk]), {"open": "1"}),
    ]


@pytest.mark.parametrize("model, fields", BROKEN_ROWS.values(), ids=BROKEN_ROWS.keys())
def test_a_broken_row_crashes_no_researcher_page_and_no_participant_page(model, fields, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"
    owner = User.objects.create_user("researcher")
    study = study_with_a_participant(owner)
    _break(study, model, fields)
    researcher = Client(raise_request_exception=False)
    researcher.force_login(owner)

    answers = {(method, url): getattr(researcher, method)(url, data).status_code
               for method, url, data in researcher_pages(study)}

    assert {key: status for key, status in answers.items() if status >= 500} == {}
    # The participant rates their last clip and answers the closing question.
    participant = Participant.objects.get()
    browser = Client(raise_request_exception=False)
    browser.cookies.update(_participant_cookie(participant))
    last = Assignment.objects.get(participant=participant, position=2)
    Assignment.objects.filter(pk=last.pk).update(shown_at=timezone.now() - timedelta(minutes=1))
    steps = [browser.get(reverse("participant-page", args=[study.key])),
             browser.post(reverse("participant-rate", args=[study.key]), {"assignment": last.token, "value": 3,
                                                                          "ended_s": 4.1, "answered_s": 4.5}),
             browser.get(reverse("participant-page", args=[study.key])),
             browser.post(reverse("participant-survey", args=[study.key]), {"q-age": "30"}),
             browser.get(reverse("participant-page", args=[study.key]))]
    # A row the participant's page cannot read is the researcher's to fix: a plain page saying
    # to come back later (503), with nothing of the row in it.
    assert [response.status_code < 500 or (response.status_code == 503 and "Not available just now" in
                                           response.content.decode()) for response in steps] == [True] * len(steps)


def test_the_controls_download_of_a_control_of_only_its_type_names_the_control(client):
    owner = User.objects.create_user("researcher")
    study = study_with_a_participant(owner)
    broken = study.controls.first()
    ControlSignal.objects.filter(pk=broken.pk).update(control={"type": "path"})
    client.force_login(owner)

    response = client.get(reverse("study-controls-download", args=[study.pk]) + "?natural=1", follow=True)

    assert response.redirect_chain[-1][0] == reverse("study-controls", args=[study.pk])
    page = html.unescape(response.content.decode())
    assert (f"No download: control signal 'walk-0' (id {broken.pk}): its control is no control "
            "description (lacks 'velocities')") in page
    assert "its control is no control description" in page.split("<table", 1)[1]  # and in the control's row


def test_editing_a_control_of_a_study_whose_system_has_no_source_is_a_409_naming_the_system(client):
    owner = User.objects.create_user("researcher")
    study = study_with_a_participant(owner)
    study.participants.all().delete()
    system = study.systems.get(name="MoGlow")
    System.objects.filter(pk=system.pk).update(checkpoint="", kind="")
    control = study.controls.first()
    client.force_login(owner)

    response = client.post(reverse("study-item-edit", args=[study.pk, "controls", control.pk]), {"name": "renamed"})

    assert response.status_code == 409
    page = html.unescape(response.content.decode())
    assert f"system 'MoGlow' (id {system.pk}): its kind '' names no source of motion" in page
    assert f"/admin/studyapp/system/{system.pk}/change/" in page
    assert ControlSignal.objects.get(pk=control.pk).name == control.name  # the rename rolled back


def test_the_admin_refuses_to_store_the_rows_the_pages_cannot_read(client):
    owner = User.objects.create_user("researcher", is_staff=True)
    owner.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    study = study_with_a_participant(owner)
    client.force_login(owner)
    control, system, participant = study.controls.first(), study.systems.get(name="MoGlow"), study.participants.get()
    refusals = {
        f"/admin/studyapp/controlsignal/{control.pk}/change/": (
            {"study": study.pk, "name": control.name, "origin": "synthetic", "control": '{"type": "path"}',
             "seconds": 4}, "its control is no control description (lacks &#x27;velocities&#x27;)"),
        f"/admin/studyapp/controlsignal/{control.pk}/change/?deep": (
            {"study": study.pk, "name": control.name, "origin": "synthetic", "control": "[" * 100_000 + "]" * 100_000,
             "seconds": 4}, "nested too deeply to read"),
        f"/admin/studyapp/system/{system.pk}/change/": (
            {"study": study.pk, "name": "MoGlow", "role": "model", "kind": "moglow", "metadata": '["moglow"]',
             "temperature": 1}, "its metadata is list, not a JSON object"),
        f"/admin/studyapp/participant/{participant.pk}/change/": (
            {"study": study.pk, "platform_id": "p1", "platform_data": "{}", "training": '{"0": 1}',
             "training_done": 1, "answers": '{"age": NaN}', "failed_checks": 0, "refused_early": 0},
            "must be a JSON list of stimulus ids"),
    }
    for url, (fields, message) in refusals.items():
        response = client.post(url, fields)
        assert response.status_code == 200 and message in response.content.decode(), url
    control.refresh_from_db(), system.refresh_from_db(), participant.refresh_from_db()
    assert control.control["type"] == "path" and "velocities" in control.control
    assert isinstance(system.metadata, dict) and participant.training != {"0": 1}


def _participant_cookie(participant: Participant):
    from django.http import HttpResponse

    from studyapp.participants.views import _remember

    return _remember(HttpResponse(), participant).cookies
