"""The plan lock holds on every path: the admin, the commands and the pages refuse what a
study that has begun keeps fixed (``studyapp.preregistration.fixed``), and what it allows is recorded
as a deviation from its plan.

The study is opened (its plan locked) and one participant has rated two of its clips; its
systems and controls were added after the lock, so the deviations that count are those after.
"""

from __future__ import annotations

import io

import pytest
from django.contrib import admin
from django.contrib.auth.models import Permission, User
from django.core.management import call_command
from django.core.management.base import CommandError
from django.test import RequestFactory

from studyapp.models import Participant, PlanDeviation, Rating, Stimulus, Study, StudyPlan, System
from tests.test_stored_data import study_with_a_participant

pytestmark = pytest.mark.django_db


@pytest.fixture
def staff(client) -> User:
    owner = User.objects.create_user("researcher", is_staff=True)
    owner.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    client.force_login(owner)
    return owner


@pytest.fixture
def study(staff) -> Study:
    study = study_with_a_participant(staff)
    assert StudyPlan.objects.filter(study=study).exists() and study.participants.exists()
    study.deviations_before = PlanDeviation.objects.filter(study=study).count()
    return study


def admin_form(row, user: User, **changes) -> dict:
    """The admin's change form of ``row`` as the browser posts it, with ``changes``."""
    model_admin = admin.site._registry[type(row)]
    request = RequestFactory().get("/")
    request.user = user
    form = model_admin.get_form(request, row)(instance=row)
    data = {name: form[name].value() for name in form.fields}
    data.update(changes)
    # A field with a callable default (the camera's dict) posts its initial value beside it, as the page has it.
    data.update({f"initial-{name}": form[name].value() for name, field in form.fields.items()
                 if field.show_hidden_initial})
    return {name: ("" if value is None else value) for name, value in data.items() if value is not False}


def posted(client, row, user: User, **changes):
    url = f"/admin/studyapp/{row._meta.model_name}/{row.pk}/change/"
    return client.post(url, admin_form(row, user, **changes))


def new_deviations(study: Study) -> list[PlanDeviation]:
    """The deviations recorded since the fixture was made (its systems and controls came after the lock)."""
    return list(PlanDeviation.objects.filter(study=study).order_by("pk")[study.deviations_before:])


def deviation_fields(study: Study) -> list[str]:
    return [deviation.field for deviation in new_deviations(study)]


@pytest.mark.parametrize("changes", [{"design": "pairwise"}, {"scale_max": 7}, {"bad_threshold": 2.5},
                                     {"natural_threshold": 4}, {"question": "How smooth?"}])
def test_the_admin_refuses_to_change_the_instrument_after_participants_started(changes, client, staff, study):
    before = Study.objects.filter(pk=study.pk).values(*changes).get()
    response = posted(client, study, staff, **changes)
    assert response.status_code == 200
    assert "participants have started this study" in response.content.decode()
    assert Study.objects.filter(pk=study.pk).values(*changes).get() == before
    assert deviation_fields(study) == []


def test_a_setting_the_admin_may_change_is_recorded_as_a_deviation(client, staff, study):
    response = posted(client, study, staff, ratings_per_stimulus=9)
    assert response.status_code == 302
    assert Study.objects.get(pk=study.pk).ratings_per_stimulus == 9
    [deviation] = new_deviations(study)
    assert (deviation.field, deviation.old, deviation.new) == ("setting.ratings_per_stimulus", 3, 9)


def test_the_admin_refuses_to_move_a_rated_clip_to_another_system(client, staff, study):
    rated = Stimulus.objects.filter(assignments__rating__isnull=False, study=study).first()
    other = study.systems.exclude(pk=rated.system_id).first()
    response = posted(client, rated, staff, system=other.pk)
    assert response.status_code == 200 and "cannot change" in response.content.decode()
    assert Stimulus.objects.get(pk=rated.pk).system_id == rated.system_id


def test_the_admin_refuses_to_edit_or_delete_a_rating(client, staff, study):
    rating = Rating.objects.filter(assignment__participant__study=study).first()
    response = posted(client, rating, staff, value=1 if rating.value != 1 else 5)
    assert response.status_code == 200 and "cannot change" in response.content.decode()
    assert Rating.objects.get(pk=rating.pk).value == rating.value
    assert client.post(f"/admin/studyapp/rating/{rating.pk}/delete/", {"post": "yes"}).status_code == 403
    selected = {"action": "delete_selected", "_selected_action": [rating.pk], "post": "yes"}
    client.post("/admin/studyapp/rating/", selected)
    assert Rating.objects.filter(pk=rating.pk).exists()


def test_the_admin_refuses_to_change_a_participants_exclusion_or_delete_their_ratings_with_them(client, staff, study):
    participant = Participant.objects.filter(study=study).first()
    response = posted(client, participant, staff, excluded=not participant.excluded)
    assert response.status_code == 200 and "cannot change" in response.content.decode()
    assert Participant.objects.get(pk=participant.pk).excluded == participant.excluded
    assert client.post(f"/admin/studyapp/participant/{participant.pk}/delete/", {"post": "yes"}).status_code == 403
    assert Participant.objects.filter(pk=participant.pk).exists()


def test_the_admin_refuses_to_change_or_delete_a_system_as_the_systems_page_does(client, staff, study):
    system = study.systems.get(name="MoGlow")
    response = posted(client, system, staff, temperature=0.5)
    assert response.status_code == 200 and "cannot change" in response.content.decode()
    assert System.objects.get(pk=system.pk).temperature == 1.0
    assert client.post(f"/admin/studyapp/system/{system.pk}/delete/", {"post": "yes"}).status_code == 403
    assert System.objects.filter(pk=system.pk).exists() and deviation_fields(study) == []


def test_generate_stimuli_with_another_seed_is_refused_by_the_command_and_the_page(client, study):
    clips = Stimulus.objects.filter(study=study).count()
    with pytest.raises(CommandError) as error:
        call_command("generate_stimuli", str(study.pk), "--seed", "7", stdout=io.StringIO())
    assert error.value.returncode == 2
    assert str(error.value) == ("the plan of this study is locked with its clips drawn with seed 0: clips of seed 7 "
                                "would be a second set, which participants would rate as the same clips")
    response = client.post(f"/studies/{study.pk}/stimuli/", {"seed": "7"})
    assert response.status_code == 409 and "clips of seed 7 would be a second set" in response.content.decode()
    assert Stimulus.objects.filter(study=study).count() == clips


def test_a_control_a_command_adds_to_a_started_study_is_recorded_as_a_deviation(study):
    call_command("add_controls", str(study.pk), "--preset", "walk-circle", stdout=io.StringIO())
    assert deviation_fields(study) == ["control.walk-circle"]
