"""Every name a definition or a bundle gives points only at the researcher's own, or at
what the server shares (``studyapp.ownership``), and a refusal tells nothing of what is
elsewhere on the server.

Tried as a hostile researcher would: another researcher's checkpoint and submitted
motion named by the digest their plan or report shows; server folders named in a
held-out control, existing or not, by a path, through ``..`` or a link; a bundle whose
sampled motion would be drawn by another researcher's clips of the same content key, or
whose controls record a take outside its folder or a folder of the server; a file that
is no BVH named where a BVH goes.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from django.contrib.auth.models import Permission, User
from django.core.files import File
from django.core.management import call_command

from generation.motion.bvh import BVHError, read_bvh
from generation.motion.npz import load_motion_npz, save_motion_npz
from generation.motion.types import Motion
from studyapp.definitions import DefinitionError, create_study_from_definition
from studyapp.models import ControlSignal, Study, System
from studyapp.researchers.setup.removal import remove_study
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.controls import add_preset_controls
from studyapp.stimuli.natural import natural_clip
from studyapp.stimuli.sources import imported_sampled_folder, sampled_path, source_of
from studyapp.stimuli.systems import add_checkpoint_system
from tests.test_hostile_bundles import bundle, members, refused, rewritten  # noqa: F401 (fixtures)
from tests.test_study_definitions import submitted_motion
from tests.test_study_researcher import files, new_study, researcher, site  # noqa: F401 (fixtures)

pytestmark = [pytest.mark.django_db, pytest.mark.slow]

SECRET = "SECRET-7f3a9c"

MODEL = """\
version: 1
the_study:
  title: Borrowed
systems:
- name: M
  role: model
  checkpoint:
    digest: {digest}
    file: m.safetensors
controls:
- name: circle
  preset: walk-circle
"""

SUBMITTED = """\
version: 1
the_study:
  title: Borrowed
systems:
- name: NAT
  role: natural
- name: Lab
  role: model
  submitted:
    digest: {digest}
    controls: []
"""

TAKE = """\
version: 1
the_study:
  title: Takes
systems:
- name: NAT
  role: natural
controls:
- name: a take
  held_out:
    take: {take}
    seconds: 1
    folders: [{folder}]
"""


def refusal(text: str, owner: User) -> str:
    """The one line a definition is refused with; nothing of it is kept."""
    studies = set(Study.objects.values_list("pk", flat=True))
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, owner, source="study.yaml")
    assert set(Study.objects.values_list("pk", flat=True)) == studies
    assert "\n" not in str(error.value)
    return str(error.value)


def another_researcher() -> User:
    return User.objects.create_user("another-researcher")


def checkpoint_study(owner: User, path: Path) -> System:
    study = new_study(owner)
    with File(path.open("rb"), name="private.safetensors") as upload:
        return add_checkpoint_system(study, "Private", upload)


# --- hole 1: another researcher's checkpoint or submitted motion, by its digest --------------

def test_a_definition_naming_another_researchers_checkpoint_digest_is_refused_as_a_digest_never_uploaded(
        researcher, site, files):
    digest = checkpoint_study(researcher, files.good).checkpoint_digest  # shown on their plan and report
    thief = another_researcher()
    made_up = "ab" * 32
    said = refusal(MODEL.format(digest=digest), thief)
    assert said == refusal(MODEL.format(digest=made_up), thief).replace(made_up, digest)
    assert said.startswith("study.yaml:8: systems[0].checkpoint.digest: no checkpoint ")
    assert str(site) not in said  # no folder of the server
    assert not System.objects.filter(study__owner=thief).exists()

    # Its owner names it, as their own definitions do.
    study = create_study_from_definition(MODEL.format(digest=digest), researcher, source="study.yaml")
    assert study.systems.get().checkpoint_digest == digest


def test_a_definition_naming_another_researchers_submitted_motion_is_refused(site, files, settings):
    theirs = submitted_motion(SimpleNamespace(root=site, files=files, settings=settings))
    digest = theirs.systems.get(name="Lab").checkpoint_digest
    thief = another_researcher()
    made_up = "cd" * 32
    said = refusal(SUBMITTED.format(digest=digest), thief)
    assert said == refusal(SUBMITTED.format(digest=made_up), thief).replace(made_up, digest)
    assert said.startswith("study.yaml:10: systems[1].submitted.digest: no submitted motion ")


def test_the_shared_checkpoints_are_named_by_anyone(researcher, site, files, settings, tmp_path):
    shared = tmp_path / "shared-models"
    shared.mkdir()
    (shared / "public.safetensors").write_bytes(files.good.read_bytes())
    (shared / "not-a-checkpoint.safetensors").write_bytes(b"not one")  # ignored, never an error
    settings.SHARED_CHECKPOINTS = shared
    digest = checkpoint_study(researcher, files.good).checkpoint_digest
    Study.objects.all().delete()  # no study of anyone's has it: it is shared alone

    study = create_study_from_definition(MODEL.format(digest=digest), another_researcher(), source="study.yaml")
    assert study.systems.get().checkpoint_digest == digest


# --- hole 3: server folders through a definition -------------------------------------------

@pytest.fixture
def outside(tmp_path, files) -> Path:
    """A folder of takes outside the motion data (another lab's, the server's), and a link to it inside."""
    folder = tmp_path / "private-takes"
    (folder / "data").mkdir(parents=True)
    for path in (files.clips / "data").iterdir():
        (folder / "data" / path.name.replace("dataset-1_", "private-")).symlink_to(path.resolve())
    return folder


def test_a_folder_outside_the_motion_data_is_refused_alike_whether_it_exists_or_not(researcher, site, files, outside,
                                                                                      settings, tmp_path):
    linked = tmp_path / "motion-with-a-link"  # MOTION_DATA, holding a link to the private folder
    (linked / "data").mkdir(parents=True)
    for path in (files.clips / "data").iterdir():
        (linked / "data" / path.name).symlink_to(path.resolve())
    (linked / "elsewhere").symlink_to(outside)
    settings.MOTION_DATA = linked
    hostile = [str(outside), str(outside / "data"), "/etc", "/", "/no/such/folder", str(outside) + "-missing",
               f"{linked}/../{outside.name}", f"{linked}/data/../../{outside.name}/data", str(linked / "elsewhere"),
               str(linked / "elsewhere" / "data"), "private-takes", "data", ".", f"{linked}:{outside}", "~", "~root"]
    take = "data/private-walk_normal_001.bvh"
    said = {folder: refusal(TAKE.format(take=take, folder=json.dumps(folder)), researcher) for folder in hostile}
    for folder, line in said.items():
        assert line == (f"study.yaml:12: controls[0].held_out.folders[0]: {folder!r} is not a motion folder you may "
                        "use: name one of the motion data folders (MOTION_DATA) or a folder inside one, or a folder "
                        "your own held-out controls were found in"), line
        assert "private-walk" not in line and "private-run" not in line


def test_a_folder_inside_the_motion_data_or_one_of_the_researchers_own_controls_is_named(researcher, site, files):
    take = "dataset-1_walk_normal_001.bvh"
    study = create_study_from_definition(TAKE.format(take=take, folder=json.dumps(str(files.clips / "data"))),
                                         researcher, source="study.yaml")
    assert study.controls.get().source_clip == take


def test_a_folder_another_researchers_controls_were_found_in_is_theirs_alone(site, files, settings):
    theirs = submitted_motion(SimpleNamespace(root=site, files=files, settings=settings))
    folder = next(c.natural["folders"][0] for c in theirs.controls.all() if c.natural)
    take = next(c.source_clip for c in theirs.controls.all() if c.natural)
    text = TAKE.format(take=take, folder=json.dumps(folder))
    assert "is not a motion folder you may use" in refusal(text, another_researcher())


# --- hole 4: a file that is no BVH, named where a BVH goes ----------------------------------

def test_a_file_that_is_no_bvh_is_refused_by_its_line_without_a_word_of_it(tmp_path):
    secret = tmp_path / "notes.bvh"
    for text, line in ((f"{SECRET} the server's key\n", 1), (f"\n\n  {SECRET}\nHIERARCHY\n", 3),
                       ("ROOT Hips\n", 1), (json.dumps({"key": SECRET}), 1)):
        secret.write_text(text)
        with pytest.raises(BVHError) as error:
            read_bvh(secret)
        assert str(error.value) == f"{secret}:{line}: not a BVH file (it does not start with HIERARCHY)"


def test_a_definitions_take_among_files_that_are_no_bvh_says_nothing_of_them(researcher, site, files, settings,
                                                                            tmp_path):
    folder = tmp_path / "motion"
    (folder / "data").mkdir(parents=True)
    (folder / "data" / "dataset-1_walk_normal_001.bvh").symlink_to((files.clips / "data" /
                                                                    "dataset-1_walk_normal_001.bvh").resolve())
    (folder / "data" / "notes.bvh").write_text(f"{SECRET}\n")
    settings.MOTION_DATA = folder
    said = refusal(TAKE.format(take="data/notes.bvh", folder=json.dumps(str(folder))), researcher)
    assert "not a BVH file (it does not start with HIERARCHY)" in said and SECRET not in said


# --- hole 2 and the bundle's names: sampled motion and held-out takes -------------------------

def planted(motion: Motion) -> Motion:
    """The same skeleton and length, moved a metre up: motion the checkpoint never sampled."""
    return Motion(motion.positions + np.array([0.0, 100.0, 0.0]), motion.fps, motion.skeleton)


def test_sampled_motion_a_bundle_carries_is_its_studys_own_and_never_another_studys_cache(
        bundle, settings, files, tmp_path):
    name = next(n for n in members(bundle) if n.startswith("sampled/"))
    key = name.removeprefix("sampled/").removesuffix(".npz")
    original = tmp_path / "original.npz"
    original.write_bytes(members(bundle)[name])
    save_motion_npz(planted(load_motion_npz(original)), tmp_path / "planted.npz")
    call_command("import_study", str(rewritten(bundle, {name: (tmp_path / "planted.npz").read_bytes()})),
                 "--owner", "researcher", stdout=io.StringIO())
    imported = Study.objects.get()
    own = imported.stimuli.get(content_key=key)

    # Another researcher's study of the same public checkpoint, preset and defaults: the same content key.
    other = new_study(another_researcher())
    with File(files.good.open("rb"), name="moglow.safetensors") as upload:
        add_checkpoint_system(other, "MoGlow", upload)
    add_preset_controls(other, ["walk-circle", "stand-still"])
    theirs = next(s for s in plan_stimuli(other)[0] if s.content_key == key)
    assert not sampled_path(theirs).exists()  # nothing sampled for it yet: it is sampled, not drawn from the bundle
    motion = source_of(theirs.system).clip(theirs).motion
    assert not np.allclose(motion.positions, load_motion_npz(tmp_path / "planted.npz").positions)

    assert sampled_path(own).is_relative_to(imported_sampled_folder(imported))  # the imported study's own motion
    assert sampled_path(own).read_bytes() == (tmp_path / "planted.npz").read_bytes()

    remove_study(imported)
    assert not imported_sampled_folder(imported).exists() and sampled_path(theirs).is_file()


def held_out_record(bundle: Path, folders: object, take: str = "data/dataset-1_walk_normal_001.bvh") -> bytes:
    """study.json with its first control made a held-out one of ``take``, found in ``folders``."""
    record = json.loads(members(bundle)["study.json"])
    record["controls"][0] |= {"origin": "held-out", "source_clip": take, "natural": {"folders": folders, "options": {}}}
    return json.dumps(record).encode()


def test_a_bundle_whose_controls_name_a_folder_or_take_outside_the_importers_is_refused(
        bundle, settings, files, outside):
    settings.MOTION_DATA = files.clips
    folders = [str(outside), "/etc", "/no/such/folder", f"{files.clips}/../{outside.name}", "relative/folder",
               f"{files.clips}:{outside}"]
    for folder in folders:
        message = refused(rewritten(bundle, {"study.json": held_out_record(bundle, [folder])}), settings)
        assert f"study.json: control 'walk-circle': {folder!r} is not a motion folder you may use" in message, message
        assert "private-walk" not in message and "private-run" not in message
    takes = ["../../private-takes/data/private-walk_normal_001.bvh", "/etc/passwd", "data/../../x.bvh"]
    for take in takes:
        message = refused(rewritten(bundle, {"study.json": held_out_record(bundle, [str(files.clips)], take)}),
                          settings)
        assert f"study.json: control 'walk-circle': its take {take!r} is no file inside a motion folder" in message
    for hostile in ("/etc", [1, 2]):
        message = refused(rewritten(bundle, {"study.json": held_out_record(bundle, hostile)}), settings)
        assert "its natural record's folders are no list of paths" in message


def test_a_take_outside_its_folders_is_never_read(settings, files, tmp_path):
    (tmp_path / "secret.bvh").write_text(f"{SECRET}\n")
    for source in ("../secret.bvh", str(tmp_path / "secret.bvh"), "data/../../secret.bvh"):
        with pytest.raises(FileNotFoundError):
            natural_clip(source, [str(files.clips)])
    assert natural_clip("data/dataset-1_walk_normal_001.bvh", [str(files.clips)]).is_file()


# --- the admin's forms: a control's take and folders, a submitted system's folder ----------------

def test_the_admin_refuses_a_control_or_system_pointing_at_folders_not_the_owners(client, settings, files, outside):
    settings.MOTION_DATA = files.clips
    staff = User.objects.create_user("staff-researcher", is_staff=True)
    staff.user_permissions.set(Permission.objects.filter(content_type__app_label="studyapp"))
    client.force_login(staff)
    study = new_study(staff)
    control = ControlSignal.objects.create(study=study, name="take", origin="held-out", seconds=1.0,
                                           control={"type": "path", "fps": 20, "velocities": [[1, 0, 0], [1, 0, 0]]},
                                           source_clip="data/dataset-1_walk_normal_001.bvh",
                                           natural={"folders": [str(files.clips)], "options": {}})
    fields = {"study": study.pk, "name": "take", "origin": "held-out", "seconds": 1, "export_id": "",
              "control": json.dumps(control.control)}
    url = f"/admin/studyapp/controlsignal/{control.pk}/change/"
    hostile = [("../../private-takes/data/private-walk_normal_001.bvh", [str(files.clips)]),
               ("/etc/passwd", [str(files.clips)]), ("data/private-walk_normal_001.bvh", [str(outside)]),
               ("data/x.bvh", ["/etc"]), ("data/x.bvh", [f"{files.clips}/../../{outside.parent.name}"])]
    for source_clip, folders in hostile:
        response = client.post(url, {**fields, "source_clip": source_clip,
                                     "natural": json.dumps({"folders": folders, "options": {}})})
        page = response.content.decode()
        assert response.status_code == 200 and ("is not a motion folder you may use" in page
                                                or "is no file inside a motion folder" in page), source_clip
    control.refresh_from_db()
    assert control.source_clip == "data/dataset-1_walk_normal_001.bvh" and control.natural["folders"] == [
        str(files.clips)]
    assert client.post(url, {**fields, "source_clip": control.source_clip,
                             "natural": json.dumps(control.natural)}).status_code == 302  # its own, as it was

    theirs = System.objects.create(study=new_study(another_researcher()), name="Lab", kind="submitted",
                                   checkpoint_digest="4" * 64, metadata={"folder": f"submitted/{'4' * 64}"})
    mine = System.objects.create(study=study, name="NAT", role="natural", kind="natural")
    response = client.post(f"/admin/studyapp/system/{mine.pk}/change/", {
        "study": study.pk, "name": "NAT", "role": "model", "kind": "submitted", "temperature": 1,
        "metadata": json.dumps(theirs.metadata)})
    assert response.status_code == 200 and "submitted motion lies in the folder named by its digest" in \
        response.content.decode()
    mine.refresh_from_db()
    assert mine.kind == "natural"
