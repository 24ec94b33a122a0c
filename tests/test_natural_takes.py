"""Natural takes of any folder without a model trained on it: the takes the seeded split
holds out are those a dataset built on the folder holds out, with the same control, and a
researcher can name takes instead."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from generation.cli import main
from generation.control import held_out_paths, take_paths
from generation.motion.clip_files import load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.npz import load_motion_npz
from generation.motion.takes import natural_takes
from tests.study_setup import link_clips

NAMES = ["walk_normal_001", "walk_normal_002", "walk_happy_001", "walk_happy_002", "walk_old_001", "walk_tired_001",
         "run_normal_001", "run_happy_001", "dash_normal_001", "dash_happy_001"]


@pytest.fixture(scope="module")
def labelled_folder(motion_data, tmp_path_factory):
    return link_clips(motion_data, tmp_path_factory.mktemp("labelled"), NAMES)


@pytest.mark.parametrize("options", [DatasetOptions(contents=("walk", "run")),
                                     DatasetOptions(holdout_fraction=0.3, seed=4)], ids=["walk-run", "seed-4"])
def test_held_out_takes_are_those_a_dataset_of_the_folder_holds_out_with_the_same_control(labelled_folder, tmp_path,
                                                                                          options):
    dataset = build_dataset(labelled_folder, options, cache_dir=tmp_path, progress=False)
    takes, read_as = natural_takes(labelled_folder, options)
    held_out = dataset.select("test", augmented=False)
    assert [take.name for take in takes] == [clip.name for clip in held_out] and len(takes) >= 2
    assert [(take.content, take.style) for take in takes] == [(clip.content, clip.style) for clip in held_out]
    assert read_as == dataset.options
    for take, clip in zip(takes, held_out):
        np.testing.assert_array_equal(take.control, dataset.clip_arrays(clip)["control"])
    for from_takes, from_dataset in zip(take_paths([(t.name, t.control) for t in takes], 20.0, 2.0, 1.0),
                                        held_out_paths(dataset, 2.0, 1.0), strict=True):
        assert from_takes.name == from_dataset.name
        np.testing.assert_array_equal(from_takes.velocities, from_dataset.velocities)
        np.testing.assert_array_equal(from_takes.lead_in, from_dataset.lead_in)
    training = natural_takes(labelled_folder, options, split="train")[0]
    assert [take.name for take in training] == [clip.name for clip in dataset.select("train", augmented=False)]


def test_named_takes_are_read_in_the_order_named_whatever_their_content(labelled_folder):
    takes, _ = natural_takes(labelled_folder, DatasetOptions(contents=("walk",)),
                             names=["dataset-1_dash_happy_001.bvh", "dataset-1_walk_old_001"])
    assert [(take.name, take.content, take.style) for take in takes] == [
        ("dataset-1_dash_happy_001", "dash", "happy"), ("dataset-1_walk_old_001", "walk", "old")]
    with pytest.raises(ValueError, match=r"no take named dataset-1_jump_001, nothing in .*labelled\d*; its takes are "
                                         r"dataset-1_dash_happy_001, dataset-1_dash_normal_001, "):
        natural_takes(labelled_folder, names=["dataset-1_walk_old_001", "dataset-1_jump_001", "nothing"])


def test_a_folder_of_one_take_holds_nothing_out_and_says_to_name_takes(clip_path, tmp_path, capsys):
    (tmp_path / "one.bvh").symlink_to(clip_path("walk_normal_001"))
    with pytest.raises(ValueError, match="no take of the 1 is held out: .* name the takes instead"):
        natural_takes(tmp_path)
    assert main(["natural", str(tmp_path), "--out", str(tmp_path / "NAT")]) == 2
    assert "name the takes instead" in capsys.readouterr().err and not (tmp_path / "NAT").exists()
    assert main(["natural", str(tmp_path), "--takes", "one", "--seconds", "2", "--out", str(tmp_path / "NAT")]) == 0
    np.testing.assert_array_equal(load_motion_npz(tmp_path / "NAT" / "one.npz").positions,
                                  load_body_motion(tmp_path / "one.bvh", 20.0, 2.0).positions)
    assert "1 natural named clips in" in capsys.readouterr().out


def test_named_takes_that_are_missing_are_refused_and_nothing_is_written(clip_path, tmp_path, capsys):
    shutil.copy(clip_path("walk_normal_001"), tmp_path / "a.bvh")
    assert main(["natural", str(tmp_path), "--takes", "a,b", "--out", str(tmp_path / "NAT")]) == 2
    assert f"no take named b in {tmp_path}; its takes are a" in capsys.readouterr().err
    assert not (tmp_path / "NAT").exists()
