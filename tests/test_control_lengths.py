"""Lengths are what they say: a held-out control (or natural clip) whose take ends before
the length asked is named by its real length, with a warning on the page and the command
line; and ``natural`` takes the contents ``build-dataset`` takes."""

from __future__ import annotations

import io

import numpy as np
import pytest
from django.core.management import call_command

from generation.cli import main
from generation.control import length_warning, shorter_than_asked, take_paths
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from tests.test_study_held_out_lead_in import path_study, post_held_out
from tests.test_study_researcher import files, researcher, site  # noqa: F401 (fixtures)

FPS = 20


def test_a_take_shorter_than_asked_is_found_and_its_warning_gives_its_real_length():
    short, long = np.zeros((25, 3)), np.zeros((200, 3))  # a 1.25-s take and a 10-s one
    controls = take_paths([("short", short), ("long", long)], FPS, seconds=4.0, lead_in_seconds=1.0)
    assert [c.name for c in shorter_than_asked(controls, 4.0)] == ["short"]
    assert length_warning(controls[0], 4.0) == "short lasts 0.25 s (5 frames), not the 4 s asked: its take ends sooner"
    assert shorter_than_asked(controls, None) == []


@pytest.mark.django_db
def test_a_held_out_control_shorter_than_asked_is_named_by_its_length_and_the_page_warns(client, researcher, site,
                                                                                       files):
    study = path_study(client, researcher, files)
    response = post_held_out(client, study, "50", lead_in="1")
    assert response.status_code == 302
    controls = list(study.controls.filter(origin="held-out"))
    assert controls
    for control in controls:  # every take of the data ends before 51 s: each named by what it lasts
        assert control.seconds < 50 and control.name.endswith(f"-1s+{round(control.seconds, 2):g}s")
    page = client.get(response["Location"]).content.decode()
    for control in controls:
        warning = f"Warning: {control.name} lasts {control.seconds:.2f} s, not the 50 s asked: its take ends sooner"
        assert warning in page


@pytest.mark.django_db
def test_the_command_warns_of_a_held_out_control_shorter_than_asked(client, researcher, site, files):
    study = path_study(client, researcher, files)
    out, err = io.StringIO(), io.StringIO()
    call_command("add_controls", str(study.pk), "--held-out", "50", "--count", "1", stdout=out, stderr=err)
    (control,) = study.controls.filter(origin="held-out")
    assert control.name.endswith(f"-{round(control.seconds, 2):g}s") and "-50s" not in control.name
    assert f"warning: {control.name} lasts {control.seconds:.2f} s, not the 50 s asked" in err.getvalue()


@pytest.fixture
def walks_and_turns(motion_data_2, tmp_path):
    """Two walks and two turning walks of the second dataset, with its label files."""
    folder = tmp_path / "takes"
    (folder / "data").mkdir(parents=True)
    (folder / "cfg").symlink_to(motion_data_2 / "cfg")
    for content in ("walk", "walk-turn-left"):
        for take in ("normal_001", "normal_002"):
            for suffix in (".bvh", ".json"):
                name = f"dataset-2_{content}_{take}{suffix}"
                (folder / "data" / name).symlink_to(motion_data_2 / "data" / name)
    return folder


def test_natural_takes_the_held_out_takes_of_every_content_as_build_dataset_does(walks_and_turns, tmp_path):
    assert main(["natural", str(walks_and_turns), "--out", str(tmp_path / "NAT"), "--seconds", "1"]) == 0
    exported = sorted(p.stem for p in (tmp_path / "NAT").glob("*.npz"))
    dataset = build_dataset(walks_and_turns, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)
    held_out = sorted(clip.name for clip in dataset.select("test", augmented=False))
    assert exported == held_out and any("walk-turn-left" in name for name in exported)
