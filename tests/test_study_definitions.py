"""A study as one file: describe -> create -> describe gives the same file, for every
kind of study the researcher's pages make.

Each builder makes a study the way the pages do, through the same services: tiny
MoGlows and an ERD trained on real clips (``study_setup``), held-out takes of those
clips, presets, files of paths, submitted motion (the study's own exported natural
clips), questions, and every design. Making the definition into a new study must give
the same file and the same rows: the same controls frame by frame, the same checkpoints.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from types import SimpleNamespace

import pytest
from django.contrib.auth.models import User
from django.core.files import File
from django.core.files.uploadedfile import SimpleUploadedFile
from django.core.management import call_command

from generation.render.camera import Camera
from studyapp.definitions import DefinitionError, create_study_from_definition, definition_yaml, describe_study
from studyapp.models import Question, Study, System
from studyapp.researchers.setup.editing import rename_control
from studyapp.stimuli.control_export import write_bundle
from studyapp.stimuli.controls import (add_control_file, add_held_out_controls, add_label_controls,
                                       add_preset_controls)
from studyapp.stimuli.submissions import add_submitted_system, read_folder
from studyapp.stimuli.systems import add_checkpoint_system, add_natural_system
from tests.study_setup import study_files

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def files(motion_data, tmp_path_factory) -> SimpleNamespace:
    return study_files(motion_data, tmp_path_factory.getbasetemp())


@pytest.fixture
def site(settings, tmp_path, files):
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"
    settings.VAR_DIR.mkdir()
    (settings.VAR_DIR / "cache").symlink_to(files.root / "var" / "cache")  # the checkpoints' training data
    settings.MOTION_DATA = files.clips
    return SimpleNamespace(root=tmp_path, files=files, settings=settings)


def new_study(**fields) -> Study:
    owner, _ = User.objects.get_or_create(username="researcher")
    study = Study(owner=owner, title="Locomotion", video_width=160, video_height=120, **fields)
    study.full_clean()  # as the study page checks it
    study.save()
    return study


def checkpoint(study: Study, path, name: str, role: str = System.Role.MODEL, temperature: float = 1.0) -> System:
    with File(path.open("rb"), name=path.name) as upload:
        return add_checkpoint_system(study, name, upload, role, temperature)


def path_file(study: Study) -> None:
    """Two paths of a file: one named as a file name, one whose name is none (no export id)."""
    add_control_file(study, SimpleUploadedFile("paths.yaml", b"- segments: [{type: straight, speed: 100, seconds: 1},"
                                                             b" {type: curve, turn_rate: 20, seconds: 1}]\n"
                                                             b"- name: a slow sidestep\n"
                                                             b"  segments: [{type: sidestep, speed: 40, seconds: 2}]\n"))


def questions(study: Study) -> None:
    Question.objects.create(study=study, part="before", name="device", text="Which device do you use?",
                            choices="computer\nphone\ntablet", accepted="computer\ntablet", order=0)
    Question.objects.create(study=study, part="after", name="comments", text="Anything else?", kind="text",
                            required=False, order=1)
    Question.objects.create(study=study, part="after", name="age", text="How old are you?", kind="number",
                            minimum=18, maximum=99, order=0)


def models_study(site, **fields) -> Study:
    """MoGlow, an early MoGlow as BAD at another temperature, NAT; held-out takes with a
    lead-in, presets (one renamed: its export id stays) and a file of paths."""
    study = new_study(**fields)
    checkpoint(study, site.files.good, "MoGlow")
    checkpoint(study, site.files.early, "Early", System.Role.BAD, temperature=0.8)
    add_natural_system(study)
    add_held_out_controls(study, 1.0, None, 0.5)
    add_preset_controls(study, ["walk-circle", "stand-still"])
    rename_control(study.controls.get(name="walk-circle"), "circle")  # as the controls page renames
    path_file(study)
    return study


def single_with_everything(site) -> Study:
    study = models_study(site, platform=Study.Platform.PROLIFIC, completion_code="C0MPL3TE",
                         screen_out_code="SCREENED", stopped_code="STOPPED",
                         redirect_url="https://app.prolific.com/submissions/complete?cc=C0MPL3TE",
                         instructions="Watch each clip.\nThen rate it.", instructed_checks=2,
                         stop_after_failed_checks=1, bad_threshold=3.5, device_check=True, min_screen_width=1024,
                         min_screen_height=600, training_clips=2, require_full_play=False, expected_effect=0.5,
                         camera={**Camera().to_dict(), "azimuth": 10.0, "distance": 300.0, "follow": False})
    questions(study)
    return study


def side_by_side(site) -> Study:
    return models_study(site, design="side-by-side", scale_min=0, scale_max=100, pages_per_participant=5)


def side_by_side_on_five_points(site) -> Study:  # not the design's own 0-100
    return models_study(site, design="side-by-side", pages_per_participant=5)


def pairwise(site) -> Study:
    return models_study(site, design="pairwise", platform=Study.Platform.MTURK, completion_code="MTURK-1")


def pairwise_abx_with_strengths(site) -> Study:
    return models_study(site, design="pairwise", abx=True, preference_strengths=3, natural_checks=0)


def appropriateness(site) -> Study:
    study = models_study(site, design="appropriateness", pages_per_participant=6)
    questions(study)
    return study


def label_controlled(site) -> Study:
    """An ERD (actions and styles): held-out label controls and chosen pairs."""
    site.settings.MOTION_DATA = site.files.labelled
    study = new_study()
    checkpoint(study, site.files.erd, "ERD")
    add_natural_system(study)
    add_held_out_controls(study, 1.0)
    add_label_controls(study, ["walk"], ["happy", "normal"], 1.0)
    return study


def submitted_motion(site) -> Study:
    """No checkpoint: held-out takes of a folder, NAT, another lab's motion for them (the
    study's own natural clips, exported as the controls page exports them), and a preset
    added after it, which the lab's motion has no clip of. The takes are of a folder
    outside MOTION_DATA."""
    site.settings.MOTION_DATA = site.root / "no-motion-data"  # the takes are found where the definition says
    study = new_study(design="pairwise")
    add_held_out_controls(study, 1.5, 2, folders=[str(site.files.clips)])
    add_natural_system(study)
    exported = site.root / "exported"
    write_bundle(study, exported, natural=True)
    add_submitted_system(study, "Lab", read_folder(exported / "natural"), System.Role.MODEL, "lab.zip")
    add_preset_controls(study, ["walk-straight"])
    return study


BUILDERS = [single_with_everything, side_by_side, side_by_side_on_five_points, pairwise, pairwise_abx_with_strengths,
            appropriateness, label_controlled, submitted_motion]


def reading(natural: dict) -> dict:
    """Where a held-out take was found and how it is read: the recorded options but the
    content labels the seeded split chose its takes among, which a take named again
    (as a definition names it) is not chosen by."""
    return {**natural, "options": {k: v for k, v in natural["options"].items() if k != "contents"}} if natural else {}


def rows(study: Study) -> dict:
    """What a study's definition must carry over: its systems and controls as stored."""
    return {
        "systems": sorted((s.name, s.role, s.kind, s.checkpoint, s.checkpoint_digest, s.temperature,
                           s.metadata.get("file"), s.metadata.get("controls")) for s in study.systems.all()),
        "controls": sorted((c.name, c.origin, c.control, c.export_id, c.source_clip, reading(c.natural), c.seconds)
                           for c in study.controls.all()),
        "questions": [(q.part, q.order, q.name, q.choices, q.accepted) for q in study.questions.all()],
        "camera": study.camera,
    }


@pytest.mark.django_db
@pytest.mark.parametrize("build", BUILDERS, ids=lambda build: build.__name__)
def test_describe_create_describe_is_a_fixed_point(site, build):
    study = build(site)
    text = definition_yaml(study)

    made = create_study_from_definition(text, study.owner, source="study.yaml")

    assert made.pk != study.pk and not made.is_open
    assert definition_yaml(made) == text
    assert rows(made) == rows(study)


@pytest.mark.django_db
def test_the_definition_names_systems_by_digest_and_controls_by_how_they_are_made(site):
    study = single_with_everything(site)
    definition = describe_study(study)
    systems = {s["name"]: s for s in definition["systems"]}
    moglow = study.systems.get(name="MoGlow")
    assert systems["MoGlow"]["checkpoint"] == {"digest": moglow.checkpoint_digest, "file": "moglow.safetensors",
                                               "kind": "moglow"}
    assert systems["Early"]["role"] == "bad" and systems["Early"]["temperature"] == 0.8
    assert systems["NAT"] == {"name": "NAT", "role": "natural"}
    controls = {c["name"]: c for c in definition["controls"]}
    assert controls["circle"] == {"name": "circle", "export_id": "walk-circle", "preset": "walk-circle"}
    assert controls["a slow sidestep"]["export_id"] == "" and controls["a slow sidestep"]["path"]["fps"] == 20.0
    held_out = [c["held_out"] for c in definition["controls"] if "held_out" in c]
    assert held_out and all(h["lead_in"] == 0.5 and h["seconds"] == 1.0 and h["take"].startswith("data/")
                            and "folders" not in h for h in held_out)  # MOTION_DATA's, wherever it is
    assert [(q["part"], q["name"]) for q in definition["questions"]] == [
        ("after", "age"), ("after", "comments"), ("before", "device")]
    assert definition["crowd_platform"]["stopped_code"] == "STOPPED"
    assert definition["video_and_camera"]["camera"]["follow"] is False


@pytest.mark.django_db
def test_the_commands_write_a_definition_and_make_a_study_of_it(site):
    study = pairwise_abx_with_strengths(site)
    out = site.root / "study.yaml"
    said = io.StringIO()
    call_command("describe_study", study.key, "--out", str(out), stdout=said)
    assert out.read_text() == definition_yaml(study) and str(out) in said.getvalue()
    printed = io.StringIO()
    call_command("describe_study", str(study.pk), stdout=printed)
    assert printed.getvalue() == out.read_text()

    made = io.StringIO()
    call_command("create_study", "researcher", "--from", str(out), stdout=made)
    copy = Study.objects.get(pk=int(made.getvalue()))
    assert definition_yaml(copy) == out.read_text() and copy.owner.username == "researcher"


@pytest.mark.django_db
def test_takes_outside_motion_data_are_named_with_their_folder_and_unit(site):
    study = submitted_motion(site)
    held_out = [c["held_out"] for c in describe_study(study)["controls"] if "held_out" in c]
    assert held_out and all(h["folders"] == [str(site.files.clips)] and h["unit"] == 1.0 and h["up"] == "y"
                            for h in held_out)
    lab = next(s for s in describe_study(study)["systems"] if s["name"] == "Lab")
    assert lab["submitted"]["file"] == "lab.zip" and len(lab["submitted"]["controls"]) == 2


@pytest.mark.django_db
def test_the_documented_definition_is_the_demos_study_and_makes_it_again(settings, tmp_path, motion_data, motion_data_2,
                                                                        demo_dataset_cache):
    """docs/running-a-study.md's example, made on the demo's data with its committed models."""
    from generation.store import keep
    from studyapp import demo

    guide = (Path(__file__).resolve().parents[1] / "docs" / "running-a-study.md").read_text()
    text = guide.split("as `describe_study` writes it:\n\n```yaml\n", 1)[1].split("```\n", 1)[0]
    settings.CHECKPOINT_ROOT, settings.VAR_DIR = tmp_path / "checkpoints", tmp_path / "var"
    settings.MOTION_DATA = os.pathsep.join(map(str, (motion_data, motion_data_2)))  # the demo's data
    (tmp_path / "var").mkdir()
    (tmp_path / "var" / "cache").symlink_to(demo_dataset_cache)  # the demo's dataset, prepared once per run
    for _, _, _, file, _ in demo.DEMO_MODELS:
        keep(demo.COMMITTED_MODELS / file, settings.CHECKPOINT_ROOT)
    owner = User.objects.create_user("researcher")

    study = create_study_from_definition(text, owner, source="running-a-study.md")

    assert study.title == demo.DEMO_STUDY and definition_yaml(study) == text
    assert sorted(study.systems.values_list("name", flat=True)) == ["BAD", "MoGlow", "NAT", "RNN", "VAE"]


HELD_OUT = """\
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
    seconds: {seconds}
    up: {up}
"""


@pytest.mark.django_db
@pytest.mark.parametrize("take, seconds, up, problems", [
    ("data/dataset-1_walk_old_002.bvh", 100, "x", [
        "study.yaml:11: controls[0].held_out.seconds: Ensure this value is less than or equal to 60.0.",
        "study.yaml:12: controls[0].held_out.up: Select a valid choice. x is not one of the available choices."]),
    ("data/no_such_take.bvh", 1, "y", ["study.yaml:9: controls[0]: cannot read the motion data at"]),
    ("data/dataset-1_walk_old_002.bvh", 59, "y", [  # longer than the take: refused, not cut short silently
        "study.yaml:11: controls[0].held_out.seconds: data/dataset-1_walk_old_002.bvh lasts "]),
])
def test_held_out_takes_are_checked_as_the_controls_page_checks_them(site, take, seconds, up, problems):
    owner = User.objects.create_user("researcher")
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(HELD_OUT.format(take=take, seconds=seconds, up=up), owner, source="study.yaml")
    assert [line[:len(problem)] for line, problem in zip(error.value.lines(), problems)] == problems
    assert len(error.value.lines()) == len(problems) and not Study.objects.exists()


@pytest.mark.django_db
def test_label_controls_are_checked_as_the_controls_page_checks_them(site):
    site.settings.MOTION_DATA = site.files.labelled
    study = label_controlled(site)
    text = definition_yaml(study).replace("action: walk", "action: moonwalk", 1)
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, study.owner, source="study.yaml")
    line = text.splitlines().index("    action: moonwalk") + 1
    first = next(i for i, control in enumerate(describe_study(study)["controls"]) if "labels" in control)
    assert str(error.value) == (f"study.yaml:{line}: controls[{first}].labels.action: Select a valid choice. moonwalk "
                                "is not one of the available choices.")
    assert Study.objects.count() == 1


@pytest.mark.django_db
def test_submitted_motion_that_no_longer_matches_its_controls_is_refused_on_one_line(site):
    study = submitted_motion(site)
    exported = next(c for c in describe_study(study)["controls"] if "held_out" in c)["export_id"]
    text = definition_yaml(study).replace(f"export_id: {exported}", "export_id: renamed-elsewhere")
    with pytest.raises(DefinitionError) as error:
        create_study_from_definition(text, study.owner, source="study.yaml")
    line = next(i for i, row in enumerate(text.splitlines(), 1) if row == "- name: Lab")
    said = str(error.value)
    assert said.startswith(f"study.yaml:{line}: systems[") and "the submitted motion was not registered: " in said
    assert "renamed-elsewhere: no file: refused" in said and "\n" not in said
    assert Study.objects.count() == 1
