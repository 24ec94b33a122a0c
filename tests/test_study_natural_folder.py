"""Natural motion from any folder: a study's held-out controls and its NAT clips from a
folder of BVH files that no checkpoint was trained on (the takes the seeded split holds
out, or takes the researcher names), on the controls page and with ``add_controls``; and
in a study with checkpoints, named takes only among those their training held out."""

from __future__ import annotations

import html
import io

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from generation.motion.clip_files import LOCOMOTION, load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from studyapp.models import ControlSignal, Stimulus, System
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.controls import natural_options
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.stimuli.natural import natural_motion
from tests.study_setup import link_clips
from tests.test_study_researcher import (files, new_study, queue, researcher, run_task, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)

# Takes of dataset 1 that none of the test checkpoints was trained on.
UNSEEN = ["walk_active_001", "walk_angry_001", "walk_childish_001", "run_old_001", "run_sad_001"]


@pytest.fixture
def unseen(motion_data, tmp_path, settings):
    """MOTION_DATA: a folder of takes no checkpoint was trained on."""
    settings.MOTION_DATA = link_clips(motion_data, tmp_path / "unseen", UNSEEN)
    return settings.MOTION_DATA


@pytest.mark.django_db
def test_a_studys_nat_comes_from_a_folder_no_checkpoint_was_trained_on(client, researcher, site, unseen, queue,
                                                                      tmp_path):
    study = new_study(researcher)
    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert 'name="takes"' in page and 'name="unit"' in page and 'name="up"' in page
    response = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "count": ""})
    assert response.status_code == 302, html.unescape(response.content.decode())[-2000:]
    # The takes that training on the folder would hold out: its seeded split, built here as a dataset.
    dataset = build_dataset(unseen, DatasetOptions(contents=LOCOMOTION), cache_dir=tmp_path / "cache", progress=False)
    held_out = sorted(clip.name for clip in dataset.select("test", augmented=False))
    assert len(held_out) == 2
    controls = list(study.controls.order_by("name"))
    assert [c.source_clip for c in controls] == [f"data/{name}.bvh" for name in held_out]
    assert [c.name for c in controls] == [f"{name}-2s" for name in held_out]
    for control in controls:
        options = natural_options(control)
        assert (options.fps, options.scale, options.up) == (20.0, 1.0, "y")  # centimetres and y up, detected
        np.testing.assert_allclose(control.control["velocities"],
                                   dataset.clip_arrays(next(c for c in dataset.select("test", augmented=False)
                                                            if f"{c.name}-2s" == control.name))["control"][:40],
                                   atol=1e-3)

    # Takes named by the researcher, whatever the split; and presets at the same frame rate.
    trained = [f"dataset-1_{name}" for name in UNSEEN if f"dataset-1_{name}" not in held_out][:2]
    named = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2",
                                                           "takes": f"{trained[0]}.bvh, {trained[1]}"})
    assert named.status_code == 302
    assert sorted(study.controls.values_list("name", flat=True)) == sorted(f"{n}-2s" for n in held_out + trained)
    assert client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle"]}).status_code == 302
    assert study.controls.get(name="walk-circle").control["fps"] == 20.0
    unknown = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "takes": "nobody"})
    assert unknown.status_code == 400 and "no take named nobody in" in html.unescape(unknown.content.decode())
    furlongs = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2", "unit": "furlong"})
    assert furlongs.status_code == 400
    assert "scale must be auto, a unit (mm, cm, in, cmu, ft, m) or a number, got 'furlong'" in html.unescape(
        furlongs.content.decode())

    assert client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"}).status_code == 302
    stimuli, _ = plan_stimuli(study)
    natural = [s for s in stimuli if s.system.role == System.Role.NATURAL]
    takes = {c.name: c for c in study.controls.filter(origin=ControlSignal.Origin.HELD_OUT)}
    assert {s.control.name for s in natural} == set(takes) and len(takes) == 4
    queue_stimuli(natural)
    for stimulus in natural:
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
        stimulus.refresh_from_db()
        assert stimulus.duration_s == pytest.approx(2.0) and stimulus.video_path().is_file()
        control = stimulus.control
        take = load_body_motion(unseen / control.source_clip, 20.0, 2.0)
        np.testing.assert_array_equal(natural_motion(control, natural_options(control)).positions, take.positions)


@pytest.mark.django_db
def test_add_controls_takes_held_out_takes_of_a_named_folder_in_a_given_unit(researcher, site, unseen, tmp_path,
                                                                            settings):
    study = new_study(researcher)
    settings.MOTION_DATA = tmp_path / "elsewhere"  # no such folder: the takes come from --folder
    out = io.StringIO()
    call_command("add_controls", str(study.pk), "--held-out", "2", "--folder", str(unseen), "--takes",
                 "dataset-1_run_old_001", "--scale", "cm", "--up", "y", stdout=out)
    control = study.controls.get()
    assert (control.name, control.source_clip) == ("dataset-1_run_old_001-2s", "data/dataset-1_run_old_001.bvh")
    assert control.natural["folders"] == [str(unseen)]
    np.testing.assert_array_equal(natural_motion(control, natural_options(control)).positions,
                                  load_body_motion(unseen / control.source_clip, 20.0, 2.0).positions)
    with pytest.raises(CommandError, match="--folder, --takes, --scale and --up choose the held-out takes"):
        call_command("add_controls", str(study.pk), "--preset", "walk-circle", "--takes", "x", stdout=out)
    with pytest.raises(CommandError, match=f"cannot read the motion data at {tmp_path / 'nowhere'}: motion folder"):
        call_command("add_controls", str(study.pk), "--held-out", "2", "--folder", str(tmp_path / "nowhere"),
                     stdout=out)


@pytest.mark.django_db
def test_with_checkpoints_named_takes_must_be_among_those_their_training_held_out(client, researcher, site, files,
                                                                                 settings):
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    page = client.get(f"/studies/{study.pk}/controls/").content.decode()
    assert 'name="takes"' in page and 'name="unit"' not in page  # the checkpoints read their data in its own unit
    trained = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2",
                                                             "takes": "dataset-1_walk_normal_001"})
    assert trained.status_code == 400
    assert ("the study's checkpoints may have been trained on dataset-1_walk_normal_001: named takes must be among "
            "the takes held out of their data (dataset-1_run_happy_001, dataset-1_walk_old_002)"
            in html.unescape(trained.content.decode()))
    held = client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2",
                                                          "takes": "dataset-1_walk_old_002"})
    assert held.status_code == 302
    assert list(study.controls.values_list("name", flat=True)) == ["dataset-1_walk_old_002-2s"]
    with pytest.raises(CommandError, match="the study's checkpoints fix the unit and up axis"):
        call_command("add_controls", str(study.pk), "--held-out", "2", "--scale", "m", stdout=io.StringIO())


@pytest.mark.django_db
def test_a_checkpoint_is_refused_where_the_studys_controls_run_at_another_frame_rate(client, researcher, site, files):
    study = new_study(researcher)
    assert client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": ["walk-circle"]}).status_code == 302
    control = study.controls.get()
    control.control = {**control.control, "fps": 30.0}  # as if added from takes read at 30 fps
    control.save()
    response = upload_checkpoint(client, study, files.good.read_bytes())
    assert response.status_code == 400
    assert ("this checkpoint was trained at 20 fps and cannot follow the study's controls at another frame rate "
            "(walk-circle); remove them first" in html.unescape(response.content.decode()))
    assert not study.systems.exists()
