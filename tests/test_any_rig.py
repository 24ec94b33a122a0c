"""Motion capture from rigs the project was not written on: other joint names, CMU-style
zero-offset collars, other units, z up, and Bandai-Namco's dataset-2. The same clip
must give the same features, footsteps and rendered figure whatever the rig."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from analysis.motion.footsteps import footstep_summary
from generation.motion.augment import mirror
from generation.motion.bvh import load_motion, motion_to_bvh, write_bvh
from generation.motion.clip_files import find_bvh_files, load_body_motion, read_labels
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.features import angle_feature_spec, encode_positions
from generation.motion.root import RootOptions, limb_root_pairs
from generation.motion.symmetry import left_right_pairs
from generation.motion.unit_detection import choose_units
from generation.motion.skeleton_units import Units, skeleton_size
from generation.render import Camera
from generation.render.draw import FrameDrawer
from measures.feet import choose_foot_joints
from tests.rig_variants import CMU_NAMES, CONVENTIONS, convention_names, renamed, write_variants

FPS = 20.0
SOURCES = {"dataset-1": ("motion_data", "dataset-1_walk_normal_001"),
           "dataset-2": ("motion_data_2", "dataset-2_walk_normal_001")}


@pytest.fixture(scope="module", params=sorted(SOURCES))
def variants(request, tmp_path_factory):
    """A real walk and its copies as other rigs would write it."""
    fixture, stem = SOURCES[request.param]
    source = request.getfixturevalue(fixture) / "data" / f"{stem}.bvh"
    return source, write_variants(source, tmp_path_factory.mktemp("rigs"))


def read_as_detected(path):
    choice = choose_units([path])
    units = choice.units
    return load_body_motion(path, FPS, scale=units.scale, up=units.up), units


def joint_map(original, variant) -> list[int]:
    """The variant's index of each of the original body's joints."""
    names = [CMU_NAMES[n] if variant.skeleton.n_joints != original.skeleton.n_joints else n
             for n in original.skeleton.names]
    return [variant.skeleton.index(n) for n in names]


def figure_box(motion) -> np.ndarray:
    """Width and height in pixels of the drawn figure's joints in the middle frame."""
    drawer = FrameDrawer(motion, Camera(), (320, 240))
    k = len(drawer) // 2
    pixels = drawer.camera.to_pixels(drawer.joints_cam[k, drawer.shown_joints], drawer.size)
    return pixels.max(axis=0) - pixels.min(axis=0)


def test_bandai_namco_data_is_detected_as_centimetres_with_y_up(motion_data, motion_data_2):
    for folder in (motion_data, motion_data_2):
        assert choose_units(find_bvh_files(folder)).units == Units(1.0, "y")


def test_every_variant_is_read_in_its_own_unit_and_up_axis(variants):
    _, paths = variants
    expected = {"cmu": Units(1.0, "y"), "metres": Units(100.0, "y"), "inches": Units(2.54, "y"),
                "z-up": Units(1.0, "z"), "cmu, z-up, inches": Units(2.54, "z")}
    assert {name: read_as_detected(path)[1] for name, path in paths.items()} == expected


def test_the_same_clip_gives_the_same_features_in_every_rig(variants):
    source, paths = variants
    original = load_body_motion(source, FPS)
    features = encode_positions(original)
    assert np.abs(features.control[:, 2]).max() > 0.05  # the walk turns a little: yaw is measured
    for name, path in paths.items():
        motion, _ = read_as_detected(path)
        encoded = encode_positions(motion)
        np.testing.assert_allclose(encoded.control, features.control, atol=1e-5, err_msg=name)
        pose = encoded.pose.reshape(len(encoded.pose), -1, 3)[:, joint_map(original, motion)]
        np.testing.assert_allclose(pose, features.pose.reshape(pose.shape), atol=1e-5, err_msg=name)


def test_the_same_clip_gives_the_same_footsteps_and_figure_in_every_rig(variants):
    source, paths = variants
    original = load_body_motion(source, FPS)
    feet = choose_foot_joints(original.skeleton.names, original.skeleton.parents, [original.positions])
    steps, _ = footstep_summary([original.positions], FPS, feet)
    box = figure_box(original)
    assert 1.0 < steps["steps_per_s"] < 3.0 and 50 < box[1] < 240 * 0.6
    for name, path in paths.items():
        motion, _ = read_as_detected(path)
        feet = choose_foot_joints(motion.skeleton.names, motion.skeleton.parents, [motion.positions])
        assert feet == [joint_map(original, motion)[j] for j in choose_foot_joints(
            original.skeleton.names, original.skeleton.parents, [original.positions])], name
        assert footstep_summary([motion.positions], FPS, feet)[0] == pytest.approx(steps, nan_ok=True), name
        assert skeleton_size(motion.skeleton) == pytest.approx(skeleton_size(original.skeleton)), name
        np.testing.assert_allclose(figure_box(motion), box, atol=0.01, err_msg=name)


def test_cmu_collars_are_passed_over_for_the_limbs_below_them(variants):
    _, paths = variants
    motion, _ = read_as_detected(paths["cmu"])
    names = motion.skeleton.names
    assert [(names[l], names[r]) for l, r in limb_root_pairs(motion.skeleton)] == [
        ("LeftClavicle", "RightClavicle"), ("LeftUpLeg", "RightUpLeg")]
    spec = angle_feature_spec(motion.skeleton)
    np.testing.assert_allclose(spec.alignment.T @ spec.alignment, np.eye(3), atol=1e-9)


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_every_mirrored_bone_keeps_its_length(clip_path, convention):
    motion = load_motion(clip_path("walk_normal_001"))
    motion = renamed(motion, convention_names(motion.skeleton.names, convention))
    assert len(left_right_pairs(motion.skeleton.names)) == 8, motion.skeleton.names
    mirrored = mirror(motion)
    for parent, child in motion.skeleton.bones():
        before = np.linalg.norm(motion.positions[:, child] - motion.positions[:, parent], axis=-1)
        after = np.linalg.norm(mirrored.positions[:, child] - mirrored.positions[:, parent], axis=-1)
        # 0.01 cm: the captured rig itself is symmetric to a few micrometres only
        np.testing.assert_allclose(after, before, atol=0.01, err_msg=motion.skeleton.names[child])


def test_a_folder_mixing_units_is_refused_naming_the_outliers(motion_data, tmp_path, variants):
    _, paths = variants
    folder = tmp_path / "mixed"
    folder.mkdir()
    for name in ("walk_normal_001", "run_normal_001"):
        shutil.copy(motion_data / "data" / f"dataset-1_{name}.bvh", folder)
    shutil.copy(paths["metres"], folder / "in-metres.bvh")
    with pytest.raises(ValueError, match=r"mix units: 2 are in cm.*not in-metres\.bvh \(1\.\d+ units: m\)"):
        build_dataset(folder, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)
    # Given a scale, the files are read alike (the user has said what they are).
    build_dataset(folder, DatasetOptions(scale=1.0, up="y"), cache_dir=tmp_path / "cache", progress=False)


def test_a_folder_mixing_up_axes_is_refused_naming_the_outliers(motion_data, tmp_path, variants):
    _, paths = variants
    folder = tmp_path / "mixed"
    folder.mkdir()
    shutil.copy(motion_data / "data" / "dataset-1_walk_normal_001.bvh", folder / "a-y-up.bvh")
    shutil.copy(paths["z-up"], folder / "b-z-up.bvh")
    with pytest.raises(ValueError, match=r"mix up axes: a-y-up\.bvh stands along y, but not b-z-up\.bvh"):
        build_dataset(folder, DatasetOptions(), cache_dir=tmp_path / "cache", progress=False)


def test_a_rig_without_sides_is_refused_naming_the_file_unless_pairs_are_given(clip_path, tmp_path):
    motion = load_motion(clip_path("walk_normal_001"))
    names = tuple(f"J{j}" for j in range(motion.skeleton.n_joints))
    folder = tmp_path / "nameless"
    folder.mkdir()
    path = write_bvh(motion_to_bvh(renamed(motion, names)), folder / "nameless.bvh")
    options = DatasetOptions(scale=1.0, up="y", mirror=False, root=RootOptions(hips="J1"))
    with pytest.raises(ValueError, match=r"nameless\.bvh: cannot find the facing direction"):
        build_dataset(folder, options, cache_dir=tmp_path / "cache", progress=False)
    with pytest.raises(ValueError, match=r"nameless\.bvh: cannot measure the skeleton"):
        choose_units([path], root=RootOptions(hips="J1"))
    index = {name: j for j, name in enumerate(motion.skeleton.names)}
    pairs = {f"J{index[f'{b}_L']}": f"J{index[f'{b}_R']}" for b in ("Shoulder", "UpperArm", "UpperLeg", "LowerLeg", "Foot")}
    named = DatasetOptions(scale=None, up=None, mirror=False, root=RootOptions(hips="J1", pairs=pairs))
    dataset = build_dataset(folder, named, cache_dir=tmp_path / "cache", progress=False)
    reference = encode_positions(load_body_motion(clip_path("walk_normal_001"), FPS))
    np.testing.assert_allclose(dataset.arrays["control"], reference.control, atol=1e-4)


def test_dataset_2_labels_and_features_read_like_dataset_1(motion_data_2, tmp_path):
    folder = tmp_path / "dataset-2"
    (folder / "data").mkdir(parents=True)
    (folder / "cfg").symlink_to(motion_data_2 / "cfg")
    for path in sorted((motion_data_2 / "data").glob("dataset-2_*_normal_00[1-3].*")):
        (folder / "data" / path.name).symlink_to(path)
    assert read_labels(folder / "data" / "dataset-2_walk-turn-left_normal_001.bvh") == ("walk-turn-left", "normal")
    dataset = build_dataset(folder, DatasetOptions(contents=("walk", "run")), cache_dir=tmp_path / "cache", progress=False)
    assert dataset.options.scale == 1.0 and dataset.options.up == "y"
    speeds = {}
    for clip in dataset.select("train", augmented=False) + dataset.select("test") + dataset.select("validation"):
        speeds.setdefault(clip.content, []).append(dataset.clip_arrays(clip)["control"][:, 0].mean())
    assert sorted(speeds) == ["run", "walk"]
    assert 80 < np.median(speeds["walk"]) < 200 < np.median(speeds["run"]) < 600  # cm/s
