"""Sampled motion (VAR_DIR/sampled/<content key>.npz) goes when no stimulus refers to it.

Removing a system or a control, deleting a study in the admin, and a new temperature all
delete the sampled files of the clips they delete; a file another study's clip shares
stays, and nothing in the folder that is not a content-keyed file is touched.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
from django.contrib.auth.models import User
from django.urls import reverse

from studyapp.models import Stimulus, Study
from studyapp.researchers.setup.editing import edit_system
from studyapp.researchers.setup.removal import delete_unreferenced_samples, remove
from studyapp.stimuli.sources import sampled_folder, sampled_path
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def with_sampled_files(study: Study) -> dict[str, Path]:
    """Give every stimulus a content key like the real ones and a sampled file; the files by
    "system/control"."""
    files = {}
    for stimulus in study.stimuli.select_related("system", "control"):
        name = f"{stimulus.system.name}/{stimulus.control.name}"
        key = hashlib.sha256(f"{study.pk}/{name}".encode()).hexdigest()
        Stimulus.objects.filter(pk=stimulus.pk).update(content_key=key)
        stimulus.content_key = key
        path = sampled_path(stimulus)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(name.encode())
        files[name] = path
    return files


def share(key_of: Stimulus, with_study: Study) -> None:
    """Make a stimulus of ``with_study`` have ``key_of``'s content key (same clip, same file)."""
    other = with_study.stimuli.filter(system__name=key_of.system.name, control__name=key_of.control.name).get()
    Stimulus.objects.filter(pk=other.pk).update(content_key=key_of.content_key)


@pytest.fixture
def var(settings, tmp_path) -> Path:
    settings.VAR_DIR, settings.MEDIA_ROOT = tmp_path / "var", tmp_path / "media"
    return settings.VAR_DIR


def test_removing_a_system_deletes_its_sampled_motion_but_keeps_what_another_study_shares(var, tmp_path):
    study, other = make_study(controls=2), make_study(owner_name="another", controls=2)
    files, others = with_sampled_files(study), with_sampled_files(other)
    shared = Stimulus.objects.get(study=study, system__name="MoGlow", control__name="control-0")
    share(shared, other)
    outside = tmp_path / "outside.npz"
    outside.write_bytes(b"not the study's")
    notes, partial, link = (sampled_folder() / name for name in ("notes.txt", f".{'a' * 64}.npz.123.part",
                                                                  f"{'b' * 64}.npz"))
    notes.write_text("kept")
    partial.write_bytes(b"half a file")
    link.symlink_to(outside)  # named like sampled motion, but a link out of the folder

    assert remove(study.systems.get(name="MoGlow")) == 2
    assert not files["MoGlow/control-1"].exists()
    assert files["MoGlow/control-0"].read_bytes() == b"MoGlow/control-0"  # the other study's clip has that key
    assert all(path.exists() for name, path in files.items() if not name.startswith("MoGlow/"))
    assert all(path.exists() for path in others.values() if path != others["MoGlow/control-0"])
    assert notes.exists() and partial.exists() and link.is_symlink() and outside.read_bytes() == b"not the study's"

    remove(study.controls.get(name="control-1"))
    assert not any(path.exists() for name, path in files.items() if name.endswith("control-1"))
    assert files["RNN/control-0"].exists()


def test_deleting_a_study_in_the_admin_deletes_the_sampled_motion_only_it_used(var, client):
    study, other = make_study(controls=2), make_study(owner_name="another", controls=2)
    files, others = with_sampled_files(study), with_sampled_files(other)
    shared = Stimulus.objects.get(study=study, system__name="RNN", control__name="control-1")
    share(shared, other)
    admin = User.objects.create_superuser("admin", "admin@example.org", "pw-for-tests")
    client.force_login(admin)
    response = client.post(reverse("admin:studyapp_study_delete", args=[study.pk]), {"post": "yes"})
    assert response.status_code == 302 and not Study.objects.filter(pk=study.pk).exists()
    assert [name for name, path in files.items() if path.exists()] == ["RNN/control-1"]
    assert all(path.exists() for path in others.values() if path != others["RNN/control-1"])

    # The list page's bulk delete goes the same way.
    client.post(reverse("admin:studyapp_study_changelist"),
                {"action": "delete_selected", "_selected_action": [other.pk], "post": "yes"})
    assert not Study.objects.exists() and list(sampled_folder().iterdir()) == []


def test_a_new_temperature_deletes_the_systems_sampled_motion(var, settings):
    study = make_study(controls=2)
    files = with_sampled_files(study)
    moglow = study.systems.get(name="MoGlow")
    moglow.checkpoint, moglow.checkpoint_digest, moglow.kind = "m.safetensors", "d" * 64, "moglow"
    moglow.save()
    assert edit_system(moglow, "MoGlow", temperature=0.8) == 2
    assert [name for name, path in files.items() if not path.exists()] == ["MoGlow/control-0", "MoGlow/control-1"]
    assert delete_unreferenced_samples() == 0  # everything left is referenced
