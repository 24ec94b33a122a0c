"""The dataset builder: labels, split by take, augmentation, standardisation, cache."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from generation.motion.clip_files import contents_or_all, find_bvh_files
from generation.motion.dataset import MotionDataset, build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.splits import SPLITS, split_takes

CLIPS = [f"{c}_{s}_001" for c in ("walk", "walk-left", "run") for s in ("normal", "happy", "old")] + ["walk_normal_002"]


@pytest.fixture
def small_folder(motion_data, tmp_path):
    """A folder of links to ten real clips, their labels and the label names."""
    folder = tmp_path / "bvh"
    (folder / "data").mkdir(parents=True)
    (folder / "cfg").symlink_to(motion_data / "cfg")
    for name in CLIPS:
        for suffix in (".bvh", ".json"):
            source = motion_data / "data" / f"dataset-1_{name}{suffix}"
            (folder / "data" / source.name).symlink_to(source)
    return folder


def test_build_reads_labels_splits_by_take_and_augments_training_clips_only(small_folder, tmp_path):
    options = DatasetOptions(holdout_fraction=0.34, reverse=True)
    dataset = build_dataset(small_folder, options, cache_dir=tmp_path / "cache", progress=False)
    originals = [c for c in dataset.clips if not c.augmentation]
    assert sorted(c.name for c in originals) == sorted(f"dataset-1_{n}" for n in CLIPS)
    assert {c.content for c in originals} == {"walk", "walk-left", "run"}
    assert {c.style for c in originals} == {"normal", "happy", "old"}
    test_takes = {c.take for c in dataset.select("test")}
    validation_takes = {c.take for c in dataset.select("validation")}
    train_takes = {c.take for c in dataset.select("train")}
    assert test_takes and validation_takes and train_takes
    assert not test_takes & train_takes and not validation_takes & (train_takes | test_takes)
    assert {c.content for c in dataset.select("test")} == {"walk", "walk-left", "run"}
    assert all(c.augmentation == "" for c in dataset.select("test") + dataset.select("validation"))
    augmentations = {c.augmentation for c in dataset.select("train")}
    assert augmentations == {"", "mirror", "reverse", "mirror+reverse"}
    # Mirrored clips have no joint rotations, hence no angle features.
    for clip in dataset.clips:
        assert np.isnan(dataset.clip_arrays(clip)["angles"]).all() == ("mirror" in clip.augmentation)


def test_windows_are_standardised_with_training_statistics(small_folder, tmp_path):
    # No validation takes: a few more training takes make the moments steadier.
    dataset = build_dataset(small_folder, DatasetOptions(validation_fraction=0.0), cache_dir=tmp_path, progress=False)
    train = dataset.windows("train")
    assert train["pose"].shape[1:] == (80, 63) and train["control"].shape[1:] == (80, 3)
    assert len(dataset.labels("train")) == len(train["pose"])
    pose = train["pose"].reshape(-1, 63)
    # Overlapping windows weight frames unevenly, so the moments are close, not exact.
    assert np.abs(pose.mean(axis=0)).max() < 0.35
    assert np.abs(pose.std(axis=0) - 1).max() < 0.35
    raw = dataset.windows("train", standardize=False)
    np.testing.assert_allclose(dataset.stats["pose"].invert(train["pose"]), raw["pose"], rtol=1e-4, atol=1e-3)
    angles = dataset.windows("train", keys=("angles",))["angles"]
    assert not np.isnan(angles).any() and angles.shape[2] == dataset.angle_spec.size


def test_second_build_loads_the_cache_and_changed_options_rebuild(small_folder, tmp_path):
    first = build_dataset(small_folder, DatasetOptions(), cache_dir=tmp_path, progress=False)
    assert len(list(tmp_path.glob("dataset-*.npz"))) == 1
    start = time.perf_counter()
    again = build_dataset(small_folder, DatasetOptions(), cache_dir=tmp_path, progress=False)
    assert time.perf_counter() - start < 2.0
    assert again.fingerprint == first.fingerprint
    np.testing.assert_array_equal(again.arrays["pose"], first.arrays["pose"])
    assert again.clips == first.clips
    other = build_dataset(small_folder, DatasetOptions(fps=15.0), cache_dir=tmp_path, progress=False)
    assert other.fingerprint != first.fingerprint
    assert len(list(tmp_path.glob("dataset-*.npz"))) == 2


def test_saved_dataset_loads_without_pickles(small_folder, tmp_path):
    dataset = build_dataset(small_folder, DatasetOptions(), cache_dir=tmp_path, progress=False)
    loaded = MotionDataset.load(dataset.save(tmp_path / "copy.npz"))
    assert loaded.skeleton.names == dataset.skeleton.names
    np.testing.assert_array_equal(loaded.stats["control"].std, dataset.stats["control"].std)
    assert loaded.options == dataset.options


def test_split_holds_out_a_fraction_of_each_content_reproducibly():
    takes = [(f"walk_{i}", "walk") for i in range(20)] + [(f"run_{i}", "run") for i in range(10)]
    held = split_takes(takes, 0.1, seed=3)
    assert sum(t.startswith("walk") for t in held) == 2 and sum(t.startswith("run") for t in held) == 1
    assert split_takes(takes, 0.1, seed=3) == held
    assert split_takes(takes, 0.1, seed=4) != held


def test_unknown_content_filter_is_a_clear_error(small_folder, tmp_path):
    with pytest.raises(ValueError, match="no clips .* have content in"):
        build_dataset(small_folder, DatasetOptions(contents=("swim",)), cache_dir=tmp_path, progress=False)


def test_several_folders_pool_their_clips_and_labels(small_folder, tmp_path):
    other = tmp_path / "other"
    (other / "cfg").mkdir(parents=True)
    (other / "cfg" / "content_label.txt").write_text("lab-2_walk\nlab-2_run\n")
    (other / "cfg" / "style_label.txt").write_text("lab-2_calm\nlab-2_brisk\n")
    source = next((small_folder / "data").glob("*.bvh"))
    (other / "lab-2_take.bvh").write_bytes(source.read_bytes())
    (other / "lab-2_take.json").write_text('{"content": 1, "style": 0}')

    files = find_bvh_files([small_folder, other])
    assert files[-1].name == "lab-2_take.bvh" and len(files) == len(CLIPS) + 1
    assert find_bvh_files(f"{small_folder}{os.pathsep}{other}") == files
    assert find_bvh_files([f"{small_folder}{os.pathsep}{other}"]) == files  # as `train "$MOTION_DATA"` passes it
    dataset = build_dataset([small_folder, other], DatasetOptions(holdout_fraction=0.0, validation_fraction=0.0),
                            cache_dir=tmp_path / "cache", progress=False)
    assert {(c.name, c.content, c.style) for c in dataset.clips if c.name == "lab-2_take"} == {("lab-2_take", "run", "calm")}


def test_pooled_folders_with_the_same_clip_name_are_refused(small_folder, tmp_path):
    other = tmp_path / "copy"
    other.mkdir()
    source = next((small_folder / "data").glob("*.bvh"))
    (other / source.name).write_bytes(source.read_bytes())
    with pytest.raises(ValueError, match="also in"):
        find_bvh_files([small_folder, other])


def copy_of(small_folder, tmp_path, name: str, labels_beside: bool = False):
    """A folder of links to the clips (and their JSON labels unless told) with its own
    copies of the label-name files: in cfg/, or beside the clips."""
    folder = tmp_path / name
    data = folder / "data"
    data.mkdir(parents=True)
    for path in (small_folder / "data").iterdir():
        (data / path.name).symlink_to(path.resolve())
    names = data if labels_beside else folder / "cfg"
    names.mkdir(exist_ok=True)
    for kind in ("content", "style"):
        (names / f"{kind}_label.txt").write_text((small_folder / "cfg" / f"{kind}_label.txt").read_text())
    return folder


def test_renaming_a_label_rebuilds_the_cache_and_keeps_the_fingerprint(small_folder, tmp_path):
    folder = copy_of(small_folder, tmp_path, "renamed")
    first = build_dataset(folder, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)
    names = folder / "cfg" / "content_label.txt"
    names.write_text(names.read_text().replace("dataset-1_walk-left\n", "dataset-1_sidestep\n"))
    again = build_dataset(folder, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)
    assert {c.content for c in first.clips} == {"walk", "walk-left", "run"}
    assert {c.content for c in again.clips} == {"walk", "sidestep", "run"}
    assert again.fingerprint == first.fingerprint  # the same data: checkpoints' records stay valid
    assert len(list((tmp_path / "cache").glob("dataset-*.npz"))) == 2


def test_label_names_beside_the_clips_and_contents_with_a_dataset_prefix_are_read(small_folder, tmp_path):
    folder = copy_of(small_folder, tmp_path, "beside", labels_beside=True)
    dataset = build_dataset(folder, DatasetOptions(contents=("dataset-1_run", "walk")),
                            cache_dir=tmp_path / "cache", progress=False)
    assert {c.content for c in dataset.clips} == {"walk", "run"}
    assert {c.style for c in dataset.clips} == {"normal", "happy", "old"}


def test_a_folder_without_labels_gives_every_clip_as_one_content(small_folder, tmp_path):
    folder = tmp_path / "unlabelled"
    folder.mkdir()
    for path in (small_folder / "data").glob("*.bvh"):
        (folder / path.name).symlink_to(path.resolve())
    assert contents_or_all(folder, ("walk", "run")) is None
    assert contents_or_all(small_folder, ("walk", "run")) == ("walk", "run")
    dataset = build_dataset(folder, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)
    assert len(dataset.select("train", augmented=False)) + len(dataset.select("validation")) \
        + len(dataset.select("test")) == len(CLIPS)
    assert {(c.content, c.style) for c in dataset.clips} == {(None, None)}


def test_takes_too_short_for_a_window_are_named(small_folder, tmp_path):
    dataset = build_dataset(small_folder, DatasetOptions(), cache_dir=tmp_path, progress=False)
    short = {"dataset-1_run_normal_001", "dataset-1_walk_normal_002", "dataset-1_run_old_001"}  # 0.8, 1.0, 3.4 s
    assert {name for split in SPLITS for name in dataset.takes_without_windows(split)} == short
    warnings = dataset.window_warnings()
    assert sum(int(line.split()[0]) for line in warnings) == 3
    assert all("shorter than one 4-s window give no windows" in line for line in warnings)
    for split, role in (("train", "training"), ("validation", "validation"), ("test", "held-out")):
        named = dataset.takes_without_windows(split)
        assert any(line.startswith(f"{len(named)} {role}") and all(n in line for n in named)
                   for line in warnings) == bool(named)
