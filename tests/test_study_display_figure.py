"""A study mixing other labs' rigs: NAT from the Bandai-Namco data, and the same walks
submitted on CMU's rig and on ACCAD's (``tests/lab_rigs.py``). Every clip is drawn on the
study's one display figure; the readiness check names what differs; the mapping can be
corrected on the system's figure page and in the definition file, and a bundle carries
it; the motion export gives back each rig as it came."""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import replace

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.management import call_command
from django.core.management.base import CommandError
from django.urls import reverse

from generation.motion.bvh import load_motion, motion_to_bvh, write_bvh
from generation.motion.npz import load_motion_npz
from generation.motion.rotations import yaw_matrix
from generation.motion.types import Motion
from generation.render import Camera
from generation.render.display_figure import REQUIRED_POINTS
from generation.render.draw import FrameDrawer
from studyapp.bundles.pseudonyms import export_key
from studyapp.bundles.writing import write_study_bundle
from studyapp.definitions import definition_yaml
from studyapp.models import Stimulus, Study
from studyapp.researchers.setup.readiness import open_problems, open_warnings
from studyapp.stimuli.clips import drawn_clip
from tests.lab_rigs import LAB_RIGS, write_lab_take
from tests.test_render import decode
from tests.test_study_researcher import queue, run_task  # noqa: F401 (fixtures)

TAKE = "dataset-2_walk_masculine_001"


def manage(*args) -> str:
    out = io.StringIO()
    call_command(*map(str, args), stdout=out)
    return out.getvalue()


@pytest.fixture
def mixed_study(settings, tmp_path, queue, motion_data_2) -> Study:
    return make_mixed_study(settings, tmp_path, motion_data_2)


def make_mixed_study(settings, tmp_path, motion_data_2, size: tuple[int, int] = (160, 120), **options) -> Study:
    """NAT on the Bandai-Namco rig, and its held-out clip submitted on CMU's and ACCAD's rigs."""
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    settings.VAR_DIR, settings.MOTION_DATA = tmp_path / "var", tmp_path / "no-motion-data"
    User.objects.create_user("researcher", password="pw")
    study = Study.objects.get(pk=int(manage("create_study", "researcher", "Three rigs", "--size", *size)))
    Study.objects.filter(pk=study.pk).update(**options)
    study.refresh_from_db()
    manage("add_controls", study.pk, "--held-out", 3, "--folder", motion_data_2, "--takes", TAKE)
    manage("add_system", study.pk, "NAT", "--role", "natural")
    bundle = tmp_path / "controls"
    manage("export_controls", study.pk, "--out", bundle, "--natural")
    (natural,) = sorted((bundle / "natural").glob("*.bvh"))
    for name in ("cmu", "accad"):
        folder = tmp_path / name
        folder.mkdir()
        write_lab_take(natural, LAB_RIGS[name], folder / natural.name)
        manage("add_system", study.pk, name.upper(), "--motion", folder)
    return study


def rendered(study: Study) -> dict[str, Stimulus]:
    manage("generate_stimuli", study.pk)
    stimuli = {s.system.name: s for s in Stimulus.objects.filter(study=study).select_related("system", "control")}
    for stimulus in stimuli.values():
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
    return stimuli


@pytest.mark.django_db
def test_a_study_of_three_rigs_draws_every_clip_on_one_figure(mixed_study, tmp_path):
    stimuli = rendered(mixed_study)
    assert sorted(stimuli) == ["ACCAD", "CMU", "NAT"]
    drawn = {name: drawn_clip(stimulus)[0] for name, stimulus in stimuli.items()}
    assert {motion.skeleton.names for motion in drawn.values()} == {REQUIRED_POINTS}  # no hands: NAT has none
    def distances(motion) -> np.ndarray:  # between every two points of every frame, wherever the clip stands
        return np.linalg.norm(motion.positions[:, :, None] - motion.positions[:, None], axis=-1)

    for name in ("CMU", "ACCAD"):  # the same take (NAT where it was, the others turned onto the control's path)
        np.testing.assert_allclose(distances(drawn[name]), distances(drawn["NAT"]), atol=1.0, err_msg=name)
    videos = {name: decode(stimulus.video_path()).astype(np.int16) for name, stimulus in stimuli.items()}
    assert videos["CMU"].shape == videos["ACCAD"].shape == (60, 120, 160, 3)
    # Both submitted clips are drawn over the control's path: they differ by no more than rendering noise, in
    # mean absolute difference of the pixels (0-255, every channel). Measured: 0.85 between the two decoded
    # videos, less than the encoding's own (2.4, the CMU video against the frames it was encoded from); 0.003
    # between the frames drawn, where 0.006 % of the pixels differ by more than 16 levels (antialiasing).
    def frames(stimulus) -> np.ndarray:
        motion, floor, path = drawn_clip(stimulus)
        drawer = FrameDrawer(motion, Camera.from_dict(mixed_study.camera), (160, 120), root_path=floor,
                             control_path=path)
        return np.stack([drawer.frame(k) for k in range(len(drawer))]).astype(np.int16)

    cmu, accad = frames(stimuli["CMU"]), frames(stimuli["ACCAD"])
    encoding = np.abs(videos["CMU"] - cmu).mean()
    between = np.abs(videos["CMU"] - videos["ACCAD"]).mean()
    drawn_apart = np.abs(cmu - accad)
    assert between < encoding, (between, encoding)
    assert drawn_apart.mean() < 0.02 and (drawn_apart.max(axis=-1) > 16).mean() < 1e-4

    # The motion export gives back each rig as it came: 22, 31 and 21 joints (the hips and below).
    out = tmp_path / "motion"
    manage("export_motion", mixed_study.pk, "--out", out)
    joints = {name: load_motion_npz(next((out / name).glob("*.npz"))).skeleton.n_joints for name in stimuli}
    assert joints == {"NAT": 21, "CMU": 31, "ACCAD": 22}


@pytest.mark.django_db
def test_the_readiness_check_names_what_could_tell_the_rigs_apart(mixed_study):
    rendered(mixed_study)
    warnings = open_warnings(mixed_study)
    assert ("the systems' motion came at different frame rates (ACCAD 120 fps, CMU 120 fps, NAT 30 fps): every clip "
            "is resampled to the study's 20 fps before it is drawn") in warnings
    assert ("the systems' skeletons differ (ACCAD 22 joints, CMU 31 joints, NAT 21 joints): every clip is drawn on "
            "the study's one display figure, each rig's joints mapped to its points (see each system's figure "
            "page)") in warnings
    assert "only CMU has hands: the display figure draws none, so that no system shows by them" in warnings
    assert open_problems(mixed_study) == []


@pytest.mark.django_db
def test_a_corrected_mapping_is_kept_from_the_page_written_in_the_definition_and_carried_by_a_bundle(
        mixed_study, client, tmp_path):
    cmu = mixed_study.systems.get(name="CMU")
    client.login(username="researcher", password="pw")
    page = reverse("study-system-figure", args=[mixed_study.pk, cmu.pk])
    shown = client.get(page)
    assert shown.status_code == 200
    assert b'<option value="LeftElbow" selected>' in shown.content and b"csrfmiddlewaretoken" in shown.content
    # Another joint for the left wrist (the hand, at the wrist's place) is kept as the one correction.
    assert client.post(page, {"point_left_wrist": "lhand", "point_left_elbow": "LeftElbow"}).status_code == 302
    cmu.refresh_from_db()
    assert cmu.figure_mapping == {"left_wrist": "lhand"}
    assert "  - dataset-2_walk_masculine_001-3s\n  figure:\n    left_wrist: lhand\n" in definition_yaml(mixed_study)

    # A point mapped to no joint is refused naming it, and nothing is kept.
    refused = client.post(page, {"point_neck": "", "point_head": "Head"} | {"point_left_wrist": "NoSuchJoint"})
    assert refused.status_code == 400 and b"the rig does not have (left_wrist: &#x27;NoSuchJoint&#x27;)" in \
        refused.content
    cmu.refresh_from_db()
    assert cmu.figure_mapping == {"left_wrist": "lhand"}

    path = tmp_path / "study.zip"
    write_study_bundle(mixed_study, path, export_key(None))
    with zipfile.ZipFile(path) as bundle:
        systems = json.loads(bundle.read("study.json"))["systems"]
    assert next(s for s in systems if s["name"] == "CMU")["figure_mapping"] == {"left_wrist": "lhand"}
    manage("import_study", path, "--owner", "researcher")
    copy = Study.objects.exclude(pk=mixed_study.pk).get()
    assert copy.systems.get(name="CMU").figure_mapping == {"left_wrist": "lhand"}


@pytest.mark.django_db
def test_submitted_motion_on_a_rig_that_lacks_a_point_is_refused_naming_it(mixed_study, tmp_path):
    (natural,) = sorted((tmp_path / "controls" / "natural").glob("*.bvh"))
    headless = [(name, "thorax" if name == "head" else parent, source)  # the head hung from the chest: no neck
                for name, parent, source in LAB_RIGS["accad"].joints if name != "neck"]
    folder = tmp_path / "no-neck"
    folder.mkdir()
    write_lab_take(natural, replace(LAB_RIGS["accad"], joints=headless), folder / natural.name)
    with pytest.raises(CommandError, match=r"its rig cannot be drawn on the study's display figure: the rig's joints "
                                           r"map to no neck: name the joint of each"):
        manage("add_system", mixed_study.pk, "No neck", "--motion", folder)
    assert not mixed_study.systems.filter(name="No neck").exists()


@pytest.mark.django_db
def test_a_system_whose_mapping_names_a_joint_its_rig_lacks_stops_the_study_opening(mixed_study):
    mixed_study.systems.filter(name="ACCAD").update(figure_mapping={"neck": "lowerneck"})
    assert open_problems(mixed_study)[1:] == [  # after: no finished clip to rate
        "ACCAD: the mapping names joints the rig does not have (neck: 'lowerneck'): correct its mapping on its figure "
        "page (systems), or its clips cannot be drawn on the study's display figure"]


@pytest.mark.django_db
def test_a_path_tolerance_set_on_the_study_lets_motion_that_strays_from_its_path_in(mixed_study, tmp_path):
    """Another lab's own natural motion: the NAT clip turned 40 degrees, so that it strays
    from its control's path by a metre and more (refused at 100 cm, taken at 400)."""
    (natural,) = sorted((tmp_path / "controls" / "natural").glob("*.bvh"))
    folder = tmp_path / "turned"
    folder.mkdir()
    motion = load_motion(natural)
    turn = yaw_matrix(np.radians(40.0))
    turned = Motion(motion.positions @ turn.T, motion.fps, motion.skeleton)
    write_bvh(motion_to_bvh(turned), folder / natural.name)
    with pytest.raises(CommandError, match=r"from the control's path \(at frame \d+\); the tolerance is 100 cm"):
        manage("add_system", mixed_study.pk, "Their NAT", "--motion", folder, "--keep-root")
    Study.objects.filter(pk=mixed_study.pk).update(path_tolerance_cm=400.0)
    said = manage("add_system", mixed_study.pk, "Their NAT", "--motion", folder, "--keep-root")
    assert "from the path (the tolerance is 400 cm)" in said
