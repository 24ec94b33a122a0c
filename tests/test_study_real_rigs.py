"""The study's commands on another lab's rig: a small study whose NAT and submitted
systems both come from a real walk on CMU's rig (``tests/lab_rigs.py``: 31 joints,
120 fps, zero-offset joints), in CMU units and in metres, with no checkpoint trained
on it: controls, systems, the controls' export, the rendered stimuli, the motion export."""

from __future__ import annotations

import io
import shutil

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.management import call_command

from generation.motion.npz import load_motion_npz
from studyapp.models import Stimulus, Study
from studyapp.stimuli.control_export import natural_in_control_frame
from studyapp.stimuli.controls import natural_options
from studyapp.stimuli.natural import natural_motion
from studyapp.stimuli.sources import source_of
from tests.test_render import decode
from tests.test_study_researcher import queue, run_task  # noqa: F401 (fixtures)


def manage(*args) -> str:
    out = io.StringIO()
    call_command(*map(str, args), stdout=out)
    return out.getvalue()


@pytest.mark.django_db
def test_a_study_of_nat_and_submitted_motion_from_the_real_cmu_rig_renders_both(settings, tmp_path, queue, lab_rigs):
    cmu, cmu_metres = lab_rigs["cmu"] / "take_01.bvh", lab_rigs["cmu-metres"] / "take_01.bvh"
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    settings.VAR_DIR, settings.MOTION_DATA = tmp_path / "var", tmp_path / "no-motion-data"
    User.objects.create_user("researcher")
    study = Study.objects.get(pk=int(manage("create_study", "researcher", "CMU walk", "--size", 160, 120)))

    said = manage("add_controls", study.pk, "--held-out", 3, "--folder", cmu.parent, "--takes", cmu.stem)
    control = study.controls.get()
    assert said.startswith(f"{control.pk} take_01-3s (held-out)")
    options = natural_options(control)
    assert options.scale == pytest.approx(2.54 / 0.45) and options.up == "y"  # CMU units, detected
    manage("add_system", study.pk, "NAT", "--role", "natural")
    bundle = tmp_path / "controls"
    manage("export_controls", study.pk, "--out", bundle, "--natural")

    lab = tmp_path / "lab"  # the same take as another lab has it: in metres, where it was captured
    lab.mkdir()
    shutil.copy(cmu_metres, lab / "take_01-3s_00.bvh")
    said = manage("add_system", study.pk, "Lab", "--motion", lab)
    assert "motion units: metres (x100 to cm), y up (unit detected" in said
    assert ("take_01-3s: take_01-3s_00.bvh: read as metres (x100 to cm), y up; resampled from 120 to 20 fps; its first "
            "60 of 85 frames (3 s); moved 4.68 m and turned +2 degrees to start at the origin facing +z" in said)
    manage("add_system", study.pk, "Exported", "--motion", bundle / "natural")  # the export is a valid submission

    manage("generate_stimuli", study.pk)
    stimuli = list(Stimulus.objects.filter(study=study).select_related("system", "control"))
    assert sorted(s.system.name for s in stimuli) == ["Exported", "Lab", "NAT"]
    for stimulus in stimuli:
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
        stimulus.refresh_from_db()
        video = decode(stimulus.video_path())
        assert video.shape == (60, 120, 160, 3) and video.std() > 10, stimulus.system.name

    # What the study shows of each: the take, as read from the CMU-unit file, at the control's start for the
    # submitted systems (the metres file differs from it by its rounding, 0.0001 cm).
    natural = natural_motion(control, options)
    clips = {s.system.name: source_of(s.system).clip(s).motion for s in stimuli}
    assert natural.skeleton.names == clips["Lab"].skeleton.names == clips["Exported"].skeleton.names
    assert natural.skeleton.n_joints == 31
    np.testing.assert_array_equal(clips["NAT"].positions, natural.positions)
    in_control_frame = natural_in_control_frame(natural, options.root).positions
    np.testing.assert_allclose(clips["Lab"].positions, in_control_frame, atol=0.01)
    np.testing.assert_allclose(clips["Exported"].positions, in_control_frame, atol=0.01)

    exported = tmp_path / "motion"
    assert manage("export_motion", study.pk, "--out", exported).splitlines()[:3] == [
        "Exported: 1 clip(s)", "Lab: 1 clip(s)", "NAT: 1 clip(s)"]
    np.testing.assert_array_equal(load_motion_npz(exported / "NAT" / "take_01-3s.npz").positions, natural.positions)
