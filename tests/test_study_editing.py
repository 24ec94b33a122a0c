"""Editing a study's systems and controls until the first participant starts: a system's
name and temperature, a control's name; owner only, 409 once anyone has started."""

from __future__ import annotations

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse

from generation.motion.clip_files import load_body_motion
from generation.motion.npz import save_motion_npz
from studyapp.models import ControlSignal, Participant, Study, System
from studyapp.stimuli.clips import content_key
from studyapp.stimuli.control_export import control_id
from studyapp.stimuli.submissions import read_stored_motion
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def researcher(study: Study) -> Client:
    client = Client()
    client.force_login(study.owner)
    return client


def sampled_study(settings, tmp_path) -> Study:
    """make_study with MoGlow sampled from a checkpoint, NAT showing natural clips and
    every clip's video on disk."""
    settings.MEDIA_ROOT = tmp_path
    study = make_study(controls=2)
    study.systems.exclude(name__in=["MoGlow", "NAT"]).delete()
    study.systems.filter(name="MoGlow").update(checkpoint="m.safetensors", checkpoint_digest="d" * 64, kind="moglow")
    study.systems.filter(name="NAT").update(kind=System.SourceKind.NATURAL)
    for stimulus in study.stimuli.all():
        stimulus.video_path().parent.mkdir(parents=True, exist_ok=True)
        stimulus.video_path().write_bytes(b"video")
    return study


def edit_url(study: Study, kind: str, item: int) -> str:
    return reverse("study-item-edit", args=[study.pk, kind, item])


def test_a_new_temperature_saves_and_deletes_the_systems_clips_to_be_sampled_again(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    moglow, natural = study.systems.get(name="MoGlow"), study.systems.get(name="NAT")
    files = [s.video_path() for s in moglow.stimuli.all()]
    client = researcher(study)
    assert 'aria-label="Edit MoGlow"' in client.get(reverse("study-systems", args=[study.pk])).content.decode()
    page = client.get(edit_url(study, "systems", moglow.pk)).content.decode()
    assert 'name="temperature"' in page and "deletes this system's clips" in page
    response = client.post(edit_url(study, "systems", moglow.pk), {"name": "MoGlow warm", "temperature": 0.8},
                           follow=True)
    assert "Saved MoGlow warm. Its 2 clip(s) were deleted: generate the stimuli to sample them at temperature 0.8." \
        in response.content.decode()
    moglow.refresh_from_db()
    assert (moglow.name, moglow.temperature, moglow.stimuli.count()) == ("MoGlow warm", 0.8, 0)
    assert not any(path.exists() for path in files) and natural.stimuli.count() == 2
    client.post(edit_url(study, "systems", moglow.pk), {"name": "MoGlow", "temperature": 0.8})
    moglow.refresh_from_db()
    assert moglow.name == "MoGlow"


def test_a_system_without_a_checkpoint_has_only_its_name_to_edit(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    natural = study.systems.get(name="NAT")
    client = researcher(study)
    assert 'name="temperature"' not in client.get(edit_url(study, "systems", natural.pk)).content.decode()
    assert client.post(edit_url(study, "systems", natural.pk), {"name": "Mocap", "temperature": 3}).status_code == 302
    natural.refresh_from_db()
    assert (natural.name, natural.temperature, natural.stimuli.count()) == ("Mocap", 1.0, 2)


def test_a_renamed_control_keeps_its_clips_under_the_keys_planning_finds(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    control = study.controls.get(name="control-0")
    videos = sorted(str(s.video_path()) for s in control.stimuli.all())
    response = researcher(study).post(edit_url(study, "controls", control.pk), {"name": "zigzag"}, follow=True)
    assert "Saved zigzag." in response.content.decode()
    control.refresh_from_db()
    assert (control.name, control.control["name"]) == ("zigzag", "zigzag")
    stimuli = list(control.stimuli.select_related("system"))
    assert sorted(str(s.video_path()) for s in stimuli) == videos and all(s.video_path().exists() for s in stimuli)
    assert all(s.content_key == content_key(study, s.system, control, s.seed) for s in stimuli)


def test_a_renamed_control_keeps_its_export_id_and_its_submitted_motion(settings, tmp_path, clip_path):
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    study = sampled_study(settings, tmp_path)
    control = study.controls.get(name="control-0")
    folder = settings.CHECKPOINT_ROOT / "submitted" / "abc"
    motion = load_body_motion(clip_path("walk_normal_001"), 20.0, 1.0)
    save_motion_npz(motion, folder / "control-0.npz")
    other_lab = System.objects.create(study=study, name="Other lab", kind=System.SourceKind.SUBMITTED,
                                      metadata={"controls": ["control-0"], "folder": "submitted/abc"})
    response = researcher(study).post(edit_url(study, "controls", control.pk), {"name": "zigzag"})
    assert response.status_code == 302
    control.refresh_from_db()
    assert (control.name, control.export_id, control_id(control)) == ("zigzag", "control-0", "control-0")
    assert read_stored_motion(other_lab, control).n_frames == motion.n_frames
    # A new control under the old name cannot take the id the renamed one keeps.
    again = ControlSignal.objects.create(study=study, name="control-0", origin="synthetic", control={"type": "path"},
                                         seconds=1.0)
    assert control_id(again) == f"control-{again.pk}"


@pytest.mark.parametrize(("kind", "posted", "field", "message"), [
    ("systems", {"name": "", "temperature": 1}, "name", "This field is required."),
    ("systems", {"name": "NAT", "temperature": 1}, "name", "this study already has a system named 'NAT'"),
    ("systems", {"name": "MoGlow", "temperature": -1}, "temperature", "greater than or equal to 0.0001"),
    ("controls", {"name": "   "}, "name", "This field is required."),
    ("controls", {"name": "control-1"}, "name", "this study already has a control named 'control-1'"),
])
def test_a_bad_edit_is_a_400_naming_the_field_and_changes_nothing(settings, tmp_path, kind, posted, field, message):
    study = sampled_study(settings, tmp_path)
    item = study.systems.get(name="MoGlow") if kind == "systems" else study.controls.get(name="control-0")
    response = researcher(study).post(edit_url(study, kind, item.pk), posted)
    assert response.status_code == 400
    assert message in " ".join(response.context["form"].errors[field])
    before = item.name
    item.refresh_from_db()
    assert item.name == before and study.stimuli.count() == 4


def test_edits_are_refused_with_409_once_a_participant_has_started(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    Participant.objects.create(study=study, platform_id="first")
    moglow, control = study.systems.get(name="MoGlow"), study.controls.get(name="control-0")
    client = researcher(study)
    edits = (("systems", moglow, {"name": "X", "temperature": 0.5}), ("controls", control, {"name": "X"}))
    for kind, item, posted in edits:
        response = client.post(edit_url(study, kind, item.pk), posted)
        assert response.status_code == 409
        page = response.content.decode()
        assert "participants have started this study, so its systems and controls are fixed" in page
        assert 'name="name"' not in page
    moglow.refresh_from_db()
    control.refresh_from_db()
    assert (moglow.name, moglow.temperature, control.name, study.stimuli.count()) == ("MoGlow", 1.0, "control-0", 4)
    assert 'aria-label="Edit MoGlow"' not in client.get(reverse("study-systems", args=[study.pk])).content.decode()


def test_another_researcher_cannot_see_or_edit_them(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    moglow = study.systems.get(name="MoGlow")
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert stranger.get(edit_url(study, "systems", moglow.pk)).status_code == 404
    assert stranger.post(edit_url(study, "systems", moglow.pk), {"name": "X", "temperature": 1}).status_code == 404
    assert researcher(study).get(edit_url(study, "studies", moglow.pk)).status_code == 404
    moglow.refresh_from_db()
    assert moglow.name == "MoGlow"


def test_an_edit_needs_the_forms_csrf_token(settings, tmp_path):
    study = sampled_study(settings, tmp_path)
    moglow = study.systems.get(name="MoGlow")
    client = Client(enforce_csrf_checks=True)
    client.force_login(study.owner)
    assert client.post(edit_url(study, "systems", moglow.pk), {"name": "X", "temperature": 1}).status_code == 403
    assert 'name="csrfmiddlewaretoken"' in client.get(edit_url(study, "systems", moglow.pk)).content.decode()
