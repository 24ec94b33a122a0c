"""Numbers a participant or a researcher types: every one is finite and within what the
renderer, the schedule and the database can do, or refused with a 400 (exit status 2 on
the command line) saying the bound, and nothing is stored.

- participants: number answers on the screening and closing questions (``nan``, ``inf``,
  400 nines, ``-1e308``): ages are whole numbers in the question's range;
- researchers: the study's settings on its form, in the admin and on the command line
  (video sizes, camera, pages, checks, scale, reservation), and a sampled system's
  temperature on the systems page, its edit page and the command line.
"""

from __future__ import annotations

import html

import pytest
from django.contrib.auth.models import Permission, User
from django.core.management import CommandError, call_command
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from generation.render.camera import Camera
from studyapp.models import Participant, Question, Study, System
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, post

pytestmark = pytest.mark.django_db


def _page(response) -> str:
    return html.unescape(response.content.decode())


def _study_with_questions() -> Study:
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="hours", text="Hours of games a week?",
                            kind=Question.Kind.NUMBER, minimum=0, maximum=168, whole_numbers=False)
    return study


HOSTILE_AGES = ["nan", "NaN", "inf", "-inf", "Infinity", "9" * 400, "-1e308", "1e308", "1e-320", "-1", "121",
                "30.5", "3e1x", "0x1E", "4 1"]


@pytest.mark.parametrize("answer", HOSTILE_AGES)
def test_a_hostile_age_on_the_screening_step_is_a_400_saying_the_range_and_stores_nothing(answer):
    study = _study_with_questions()
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")

    response = post(client, study, "screening", **{"q-age": answer})

    assert response.status_code == 400
    assert "“How old are you?”: please give a whole number from 0 to 120" in _page(response)
    participant = Participant.objects.get()
    assert participant.answers == {} and participant.screened_at is None


def test_an_age_in_range_is_stored_as_a_whole_number():
    study = _study_with_questions()
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    assert post(client, study, "screening", **{"q-age": " 41 "}).status_code == 302
    assert Participant.objects.get().answers == {"age": 41}


@pytest.mark.parametrize("answer", ["nan", "inf", "9" * 400, "-1e308", "168.5", "-0.1"])
def test_a_hostile_number_on_the_closing_questions_is_a_400_saying_the_range_and_stores_nothing(answer):
    study = _study_with_questions()
    client = Client()
    enter(client, study)
    participant = Participant.objects.get()
    now = timezone.now()
    Participant.objects.filter(pk=participant.pk).update(consented_at=now, screened_at=now, instructed_at=now,
                                                         training_done=len(participant.training), finished_at=now,
                                                         answers={"age": 30})

    response = post(client, study, "survey", **{"q-hours": answer})

    assert response.status_code == 400
    assert "“Hours of games a week?”: please give a number from 0 to 168" in _page(response)
    participant.refresh_from_db()
    assert participant.answers == {"age": 30} and participant.surveyed_at is None
    assert post(client, study, "survey", **{"q-hours": "12.5"}).status_code == 302
    assert Participant.objects.get().answers == {"age": 30, "hours": 12.5}


def test_a_number_question_needs_a_range_with_a_whole_number_in_it():
    study = make_study()
    client = Client()
    client.force_login(study.owner)
    url = reverse("study-questions", args=[study.pk])
    form = {"action": "add", "part": "before", "name": "age", "text": "Age?", "kind": "number", "required": "on",
            "whole_numbers": "on"}
    for minimum, maximum, message in [("10", "5", "the largest answer must exceed the smallest (10)"),
                                      ("0.2", "0.8", "no whole number lies from 0.2 to 0.8"),
                                      ("0", "1e300", "must be a number from -1000000000 to 1000000000"),
                                      ("nan", "5", "Enter a number.")]:
        response = client.post(url, {**form, "minimum": minimum, "maximum": maximum})
        assert response.status_code == 400 and message in _page(response), message
    assert not Question.objects.exists()
    assert client.post(url, form).status_code == 302  # left empty: 0 to 120, an age in years
    assert Question.objects.values_list("minimum", "maximum").get() == (0, 120)


# --- the study's settings ------------------------------------------------------------

def study_fields(**changes) -> dict:
    """The study form's fields, every one valid, with ``changes``."""
    fields = {"title": "Gait", "question": "How natural?", "scale_min": 1, "scale_max": 5, "label_min": "bad",
              "label_max": "good", "instructions": "Watch.", "consent_text": "OK?", "clips_per_participant": 12,
              "ratings_per_stimulus": 5, "training_clips": 2, "bad_checks": 1, "natural_checks": 1,
              "bad_threshold": 4, "natural_threshold": 2, "reservation_minutes": 60, "platform": "link",
              "redirect_url": "", "video_width": 320, "video_height": 240, "design": "single",
              "pages_per_participant": 8, "preference_strengths": 0, "instructed_checks": 0,
              "stop_after_failed_checks": 0,
              **{f"camera_{name}": v for name, v in Camera().to_dict().items() if v is not None}}
    return {**fields, **changes}


HOSTILE_SETTINGS = {
    "a 0x0 video": ({"video_width": 0, "video_height": 0}, "video_width", "must be a number from 64 to 3840"),
    "a 32766x32766 video": ({"video_width": 32766, "video_height": 32766}, "video_width",
                            "must be a number from 64 to 3840"),
    "a 3840x3840 video": ({"video_width": 3840, "video_height": 3840}, "video_width",
                          "3840×3840 is past 4K video: at most 8,294,400 pixels a frame"),
    "camera distance 1e308": ({"camera_distance": "1e308"}, "camera_distance",
                              "'distance' must be a number from 20 to 10000 (cm: 100 m at most), not 1e+308"),
    "camera fov 1e-300": ({"camera_fov": "1e-300"}, "camera_fov", "'fov' must be a number from 1 to 170"),
    "camera smoothing 1e9": ({"camera_follow_smoothing": "1e9"}, "camera_follow_smoothing",
                             "'follow_smoothing' must be a number from 0 to 10 (seconds)"),
    "99 instructed checks for 8 pages": ({"design": "side-by-side", "scale_min": 0, "scale_max": 100,
                                          "pages_per_participant": 8, "instructed_checks": 99},
                                         "instructed_checks", "must be a number from 0 to 50, not 99"),
    "300 pages on a 1-2 scale": ({"design": "side-by-side", "scale_min": 1, "scale_max": 2,
                                  "pages_per_participant": 300}, "pages_per_participant",
                                 "must be a number from 0 to 100 (one sitting), not 300"),
    "reservation minutes 99999999999": ({"reservation_minutes": 99999999999}, "reservation_minutes",
                                        "must be a number from 1 to 10080 (a week)"),
    "a scale of 1000 buttons": ({"scale_min": 1, "scale_max": 1000}, "scale_max",
                                "a button per point: at most 11 points, not 1000"),
    "a scale end of 30000": ({"design": "side-by-side", "scale_min": 0, "scale_max": 30000}, "scale_max",
                             "must be a number from -1000 to 1000"),
    "a threshold of 1e300": ({"bad_threshold": "1e300"}, "bad_threshold", "must be a number from 0 to 6"),
    "40000 ratings a stimulus": ({"ratings_per_stimulus": 40000}, "ratings_per_stimulus",
                                 "must be a number from 1 to 1000"),
    "stop after 3 of no checks": ({"stop_after_failed_checks": 3}, "stop_after_failed_checks",
                                  "a participant meets 0 instructed check(s): stopping after 3 failed never happens"),
    "a screen 99999 wide": ({"min_screen_width": 99999}, "min_screen_width", "must be a number from 0 to 7680"),
}


@pytest.fixture
def researcher(client) -> User:
    user = User.objects.create_user("researcher")
    client.force_login(user)
    return user


@pytest.mark.parametrize("changes, field, message", HOSTILE_SETTINGS.values(), ids=HOSTILE_SETTINGS.keys())
def test_a_setting_past_what_the_study_can_do_is_a_400_saying_the_bound(changes, field, message, client, researcher):
    response = client.post(reverse("study-create"), study_fields(**changes))

    assert response.status_code == 400
    errors = response.context["form"].errors
    assert field in errors and message in " ".join(errors[field]), errors
    assert not Study.objects.exists()


def test_every_setting_within_its_bounds_makes_a_study(client, researcher):
    response = client.post(reverse("study-create"), study_fields(
        video_width=3840, video_height=2160, camera_distance="10000", design="side-by-side", scale_min=0,
        scale_max=100, pages_per_participant=100, instructed_checks=49, stop_after_failed_checks=49,
        bad_checks=50, reservation_minutes=10080))
    assert response.status_code == 302, response.context["form"].errors
    assert Study.objects.get().camera["distance"] == 10000


def test_the_admin_holds_a_study_to_the_same_bounds(client):
    staff = User.objects.create_user("staff", is_staff=True)
    staff.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    client.force_login(staff)
    # 32766 x 240 stays under 4K's pixels, so the study's own check goes on to the camera.
    fields = {**study_fields(), "camera": '{"distance": 1e308}', "video_width": 32766, "reservation_minutes": 99999999999}

    response = client.post("/admin/studyapp/study/add/", fields)

    page = _page(response)
    assert response.status_code == 200 and not Study.objects.exists()
    assert "must be a number from 64 to 3840" in page and "must be a number from 1 to 10080" in page
    assert "camera: not a camera description: 'distance' must be a number from 20 to 10000" in page


@pytest.mark.parametrize("arguments, message", [
    (["--size", "0", "0"], "video_width: must be a number from 64 to 3840"),
    (["--size", "32766", "32766"], "must be a number from 64 to 3840"),
    (["--pages", "300", "--design", "pairwise"], "must be a number from 0 to 100"),
    (["--clips", "100000"], "must be a number from 1 to 200"),
])
def test_create_study_holds_to_the_same_bounds_with_exit_status_2(arguments, message):
    User.objects.create_user("researcher")
    with pytest.raises(CommandError) as refused:
        call_command("create_study", "researcher", "Gait", *arguments)
    assert refused.value.returncode == 2 and message in str(refused.value)
    assert not Study.objects.exists()


# --- a sampled system's temperature --------------------------------------------------

@pytest.mark.parametrize("temperature", ["1e308", "11", "0", "-1"])
def test_a_temperature_past_its_bound_is_refused_on_the_systems_pages(temperature, client, researcher):
    study = make_study(owner_name="researcher", controls=1)
    moglow = study.systems.get(name="MoGlow")
    System.objects.filter(pk=moglow.pk).update(checkpoint="model.safetensors")

    edit = client.post(reverse("study-item-edit", args=[study.pk, "systems", moglow.pk]),
                       {"name": "MoGlow", "temperature": temperature})
    added = client.post(reverse("study-systems", args=[study.pk]),
                        {"action": "checkpoint", "name": "Hot", "role": "model", "temperature": temperature})

    for response in (edit, added):
        assert response.status_code == 400
        assert "than or equal to" in _page(response)  # the form's own bound: 0.0001 to 10
    moglow.refresh_from_db()
    assert moglow.temperature == 1.0 and moglow.stimuli.count() == 1
    assert not study.systems.filter(name="Hot").exists()


def test_the_temperature_bound_holds_for_the_services_the_command_line_calls():
    from studyapp.researchers.setup.editing import EditRefused, edit_system
    from studyapp.stimuli.systems import UploadRefused, add_checkpoint_system

    study = make_study(controls=1)
    moglow = study.systems.get(name="MoGlow")
    moglow.checkpoint = "model.safetensors"
    with pytest.raises(EditRefused, match=r"temperature must be a number from 0.0001 to 10 .* not 1e\+308"):
        edit_system(moglow, "MoGlow", 1e308)
    with pytest.raises(UploadRefused, match="temperature must be a number from 0.0001 to 10 .* not nan"):
        add_checkpoint_system(study, "Hot", None, temperature=float("nan"))
