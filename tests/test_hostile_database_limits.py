"""Input that one database stores and the other cannot gets the same clear refusal on both.

PostgreSQL holds no NUL character in text (not even to compare with) and 32 bits in an
integer column; SQLite took both, so the same link or form was accepted by the embedded
default and a server error on the deployed study. These tests run on SQLite and again on
PostgreSQL (tests.postgres_pass): each input is a 400 naming where the problem is, and
changes nothing.
"""

from __future__ import annotations

import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import CommandError, call_command
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Question, Rating, Stimulus, Study, System
from studyapp.server.uploads.null_characters import null_character_in
from tests.study_fixtures import make_study
from tests.test_hostile_checkpoints import rewritten, tiny  # noqa: F401 (a fixture: a tiny checkpoint)
from tests.test_study_designs import SIDE_BY_SIDE, page_html, page_token
from tests.test_study_designs import through_practice as through_page_practice
from tests.test_study_participant import WATCHED, make_shown_long_ago, on_screen_token, post, through_practice

pytestmark = pytest.mark.django_db

ENTRY = {"PROLIFIC_PID": "pid-1", "STUDY_ID": "s", "SESSION_ID": "x"}


def refusal(response, where: str) -> str:
    page = response.content.decode()
    assert response.status_code == 400, page[:500]
    assert f"{where} holds a NUL character" in page, page
    return page


@pytest.mark.parametrize("parameter", ["PROLIFIC_PID", "STUDY_ID", "SESSION_ID"])
def test_a_nul_in_the_prolific_link_is_a_400_naming_the_parameter_and_enrols_nobody(parameter):
    study = make_study()
    response = Client().get(reverse("participant-enter", args=[study.key]), {**ENTRY, parameter: "pid\x00-1"})
    refusal(response, f"The query parameter {parameter}")
    assert not Participant.objects.exists()


def test_a_study_key_with_a_nul_is_not_found_as_any_missing_study():
    make_study()
    for address in ("/p/ab%00cd/", "/p/ab%00cd/now/", "/p/ab%00cd/rate/"):
        response = Client().get(address, ENTRY)
        assert response.status_code == 404 and "Not found" in response.content.decode()
    assert not Participant.objects.exists()


def test_a_nul_in_the_browser_header_or_a_parameters_name_is_a_400():
    study = make_study()
    refusal(Client(headers={"User-Agent": "Mozilla\x00"}).get(reverse("participant-enter", args=[study.key]), ENTRY),
            "The header User-Agent")
    refusal(Client().get(reverse("participant-enter", args=[study.key]), {**ENTRY, "x\x00y": "1"}),
            "The query parameter x\\0y")
    assert not Participant.objects.exists()


def test_a_nul_in_a_rating_form_is_a_400_and_stores_no_rating():
    study = make_study()
    client = Client()
    participant = through_practice(client, study)
    token = on_screen_token(client, study)
    make_shown_long_ago(participant)
    refusal(post(client, study, "rate", assignment=token + "\x00", value=3, **WATCHED), "The form field assignment")
    refusal(post(client, study, "rate", assignment=token, value="3\x00", **WATCHED), "The form field value")
    assert not Rating.objects.exists()
    assert post(client, study, "rate", assignment=token, value=3, **WATCHED).status_code == 302


def test_a_nul_in_a_page_of_several_clips_is_a_400_and_stores_nothing():
    study = make_study(**SIDE_BY_SIDE)
    client = Client()
    participant = through_page_practice(client, study)
    token = page_token(page_html(client, study))
    make_shown_long_ago(participant)
    refusal(post(client, study, "rate", page=token + "\x00", **{"value-1": 50, "value-2": 50}),
            "The form field page")
    assert not Rating.objects.exists()


def test_a_nul_in_a_questionnaire_answer_is_a_400_and_keeps_no_answer():
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="comments", text="Anything to add?",
                            kind=Question.Kind.TEXT, required=False)
    client = Client()
    client.get(reverse("participant-enter", args=[study.key]), ENTRY)
    post(client, study, "consent", agree="yes")
    refusal(post(client, study, "screening", **{"q-comments": "fine\x00"}), "The form field q-comments")
    participant = Participant.objects.get()
    assert participant.answers == {} and participant.screened_at is None


def test_a_nul_in_a_researchers_form_or_the_admins_search_is_a_400_and_changes_nothing():
    study = make_study()
    question = Question.objects.create(study=study, part=Question.Part.AFTER, name="age", text="Age?")
    researcher = Client()
    researcher.force_login(study.owner)
    refusal(researcher.post(reverse("study-edit", args=[study.pk]), {"title": "Gait\x00"}), "The form field title")
    refusal(researcher.post(reverse("study-questions", args=[study.pk]), {"action": "remove",
                                                                          "question": f"{question.pk}\x00"}),
            "The form field question")
    assert Study.objects.get(pk=study.pk).title == study.title and Question.objects.filter(pk=question.pk).exists()
    staff = Client()
    staff.force_login(User.objects.create_superuser("staff", "staff@example.org", "pw-for-tests"))
    refusal(staff.get("/admin/studyapp/participant/", {"q": "pid\x00"}), "The query parameter q")


def test_a_cookie_that_spells_a_nul_is_a_400_naming_the_cookie():
    client = Client()
    client.cookies["sessionid"] = "abcdefghijklmnop\x00"  # sent quoted, as "abcdefghijklmnop\000"
    assert '\\000"' in client.cookies["sessionid"].OutputString()
    refusal(client.get(reverse("study-list")), "The cookie sessionid")


def test_a_form_without_its_csrf_token_is_refused_as_such_whatever_it_holds():
    study = make_study()
    client = Client(enforce_csrf_checks=True)
    assert client.get(reverse("participant-enter", args=[study.key]), ENTRY).status_code == 302
    forged = client.post(reverse("participant-consent", args=[study.key]), {"agree": "yes\x00"})
    assert forged.status_code == 403 and "This page had expired" in forged.content.decode()
    assert Participant.objects.get().consented_at is None


def test_a_checkpoint_whose_description_holds_a_nul_is_refused_naming_the_field(tiny, tmp_path, settings):  # noqa: F811
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    owner = User.objects.create_user("researcher")
    study = Study.objects.create(owner=owner, title="Gait", video_width=160, video_height=120)
    researcher = Client()
    researcher.force_login(owner)
    bad = rewritten(tiny, tmp_path / "bad.safetensors", description=lambda meta: meta.update(code_version="1.0\x00"))
    response = researcher.post(reverse("study-systems", args=[study.pk]), {
        "action": "checkpoint", "name": "MoGlow", "role": "model", "temperature": "1.0",
        "checkpoint": SimpleUploadedFile("model.safetensors", bad.read_bytes())})
    assert response.status_code == 400
    assert "model.safetensors: the checkpoint&#x27;s description holds a NUL character (\\0) in code_version" in (
        response.content.decode())
    assert not System.objects.exists() and not list((tmp_path / "checkpoints").iterdir())


def test_null_character_in_names_the_path_to_the_first_nul():
    assert null_character_in({"features": {"labels": ["walk", "ru\x00n"]}}) == "features.labels.1"
    assert null_character_in({"a\x00": 1}) == "a\\0"
    assert null_character_in("plain\x00") == "the text"
    assert null_character_in({"numbers": [1, 2.5, None], "text": "fine"}) is None


@pytest.mark.parametrize("seed", [Stimulus.MAX_SEED + 1, 10**20, -1])
def test_a_seed_past_what_the_database_holds_is_a_400_naming_the_bound_and_plans_nothing(seed):
    study = make_study()
    before = list(Stimulus.objects.values_list("pk", "seed"))
    researcher = Client()
    researcher.force_login(study.owner)
    response = researcher.post(reverse("study-stimuli", args=[study.pk]), {"seed": str(seed)})
    assert response.status_code == 400
    bound = "less than or equal to 2147483647" if seed > 0 else "greater than or equal to 0"
    assert bound in response.content.decode()
    assert list(Stimulus.objects.values_list("pk", "seed")) == before


def test_the_command_refuses_a_seed_past_what_the_database_holds_with_exit_status_2():
    study = make_study()
    with pytest.raises(CommandError, match="--seed 2147483648: a seed is a whole number from 0 to 2147483647") as refused:
        call_command("generate_stimuli", str(study.pk), "--seed", str(Stimulus.MAX_SEED + 1))
    assert refused.value.returncode == 2
