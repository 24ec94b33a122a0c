"""A study on a model trained on several pooled folders (MOTION_DATA joined with ":", as
the committed MoGlow was trained on both Bandai-Namco folders): its held-out controls
come from each folder and their NAT clips are read from the folder that holds them."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile

from generation.motion.clip_files import load_body_motion
from generation.motion.dataset_options import DatasetOptions
from studyapp.models import ControlSignal, Stimulus, Study
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.controls import training_options
from studyapp.stimuli.natural import natural_motion
from studyapp.tasks import generate_stimulus
from tests.study_setup import link_clips, train_tiny_moglow

# Dataset 2's takes, in another BVH formatting; with CLIPS, two folders of walking and running.
TAKES_2 = ["walk_active_002", "walk_elderly_001", "walk_normal_001", "run_active_002", "run_normal_002"]


@pytest.fixture(scope="module")
def pooled(motion_data, motion_data_2, tmp_path_factory):
    root = tmp_path_factory.mktemp("pooled")
    first = link_clips(motion_data, root / "first")
    second = root / "second"
    (second / "data").mkdir(parents=True)
    for name in TAKES_2:
        for suffix in (".bvh", ".json"):
            (second / "data" / f"dataset-2_{name}{suffix}").symlink_to(motion_data_2 / "data" / f"dataset-2_{name}{suffix}")
    data = os.pathsep.join(map(str, (first, second)))
    checkpoint = train_tiny_moglow(data, root / "moglow.safetensors", 3, root / "var" / "cache")
    return root, data, checkpoint


@pytest.mark.django_db
def test_held_out_controls_come_from_every_pooled_folder_and_nat_reads_each_from_its_own(client, settings, pooled,
                                                                                       tmp_path):
    root, data, checkpoint = pooled
    settings.MEDIA_ROOT, settings.CHECKPOINT_ROOT = tmp_path / "media", tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"
    settings.VAR_DIR.mkdir()
    (settings.VAR_DIR / "cache").symlink_to(root / "var" / "cache")
    settings.MOTION_DATA = data
    client.force_login(User.objects.create_user("researcher", password="pw-for-tests"))
    study = Study.objects.create(owner=User.objects.get(), title="Pooled", video_width=160, video_height=120)
    assert client.post(f"/studies/{study.pk}/systems/", {
        "action": "checkpoint", "name": "MoGlow", "role": "model", "temperature": "1.0",
        "checkpoint": SimpleUploadedFile("model.safetensors", checkpoint.read_bytes())}).status_code == 302
    assert client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"}).status_code == 302

    assert client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "2"}).status_code == 302
    sources = sorted(ControlSignal.objects.values_list("source_clip", flat=True))
    assert {Path(s).stem.split("_")[0] for s in sources} == {"dataset-1", "dataset-2"}, sources

    options = training_options(study)
    folders = [Path(f) for f in data.split(os.pathsep)]
    for control in ControlSignal.objects.all():  # each read from the one folder that holds it, as training read it
        (held,) = [folder / control.source_clip for folder in folders if (folder / control.source_clip).is_file()]
        expected = load_body_motion(held, options.fps, 2.0, options.scale, options.root, options.up)
        np.testing.assert_array_equal(natural_motion(control, options).positions, expected.positions)

    plan_stimuli(study)
    for stimulus in Stimulus.objects.filter(system__role="natural"):
        Stimulus.objects.filter(pk=stimulus.pk).update(task_id=f"nat-{stimulus.pk}")  # as if sent to a worker
        assert generate_stimulus.apply((stimulus.pk,), task_id=f"nat-{stimulus.pk}").get()["status"] == "done"
    assert not Stimulus.objects.filter(system__role="natural").exclude(status="done").exists()


def test_a_missing_natural_clip_names_every_folder_it_was_looked_for_in(settings, tmp_path):
    settings.MOTION_DATA = f"{tmp_path / 'a'}{os.pathsep}{tmp_path / 'b'}"
    with pytest.raises(FileNotFoundError, match=f"data/gone.bvh is in none of the motion folders {tmp_path / 'a'}, "
                                                f"{tmp_path / 'b'} \\(MOTION_DATA\\)"):
        natural_motion(ControlSignal(source_clip="data/gone.bvh", seconds=2.0, control={"fps": 20.0}), DatasetOptions())
