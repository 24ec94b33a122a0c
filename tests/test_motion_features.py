"""MoGlow and joint-angle features, resampling, mirroring, reversal and windows, on real clips."""

from __future__ import annotations

import numpy as np
import pytest

from generation.motion import load_motion
from generation.motion.data.augment import mirror, reverse, windows
from generation.motion.features import (
    angle_feature_spec,
    decode_angles,
    decode_positions,
    encode_angles,
    encode_positions,
)
from generation.motion.kinematics import subtree_motion
from generation.motion.resample import resample
from generation.motion.root import root_trajectory
from generation.motion.rotations import expmap_to_quat, quat_to_expmap
from generation.motion.symmetry import left_right_pairs

LOCOMOTION = ("walk_normal_001", "walk-left_happy_001", "walk-back_old_001", "run_normal_001", "dash_tired_001")


def body(clip_path, name: str, fps: float = 20.0):
    motion = resample(load_motion(clip_path(name)), fps)
    return subtree_motion(motion, motion.skeleton.index("Hips"))


@pytest.mark.parametrize("name", LOCOMOTION)
def test_decoding_position_features_restores_world_positions_within_1mm(clip_path, name):
    motion = body(clip_path, name)
    features = encode_positions(motion)
    assert features.pose.shape == (motion.n_frames, 63)  # 21 joints, as MoGlow's 63-D poses
    decoded = decode_positions(features.pose, features.control, motion.fps, features.root.xz[0], features.root.yaw[0])
    assert np.abs(decoded - motion.positions).max() < 0.1  # cm


def test_pose_features_do_not_depend_on_where_the_character_stands(clip_path):
    motion = body(clip_path, "walk_normal_001")
    turned = motion.positions @ np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]]).T + [300.0, 0, -50]
    a = encode_positions(motion)
    b = encode_positions(type(motion)(turned, motion.fps, motion.skeleton))
    np.testing.assert_allclose(a.pose, b.pose, atol=1e-6)
    np.testing.assert_allclose(a.control, b.control, atol=1e-6)


def test_control_reads_forward_for_walk_and_backward_for_walk_back(clip_path):
    walk = encode_positions(body(clip_path, "walk_normal_001")).control.mean(axis=0)
    back = encode_positions(body(clip_path, "walk-back_normal_001")).control.mean(axis=0)
    assert walk[0] > 50 and back[0] < -50  # cm/s forward
    still = encode_positions(body(clip_path, "bow_normal_001")).control
    assert np.abs(still[:, :2]).mean() < 5


@pytest.mark.parametrize("representation", ["quaternion", "expmap"])
def test_angle_features_decode_back_to_the_same_motion(clip_path, representation):
    motion = body(clip_path, "run_normal_001")
    spec = angle_feature_spec(motion.skeleton, representation)
    features = encode_angles(motion, spec)
    assert features.values.shape == (motion.n_frames, spec.size)
    decoded = decode_angles(features.values, motion.skeleton, spec, motion.fps, features.root.xz[0], features.root.yaw[0])
    assert np.abs(decoded.positions - motion.positions).max() < 0.01


def test_angle_root_values_describe_upright_forward_walking(clip_path):
    motion = body(clip_path, "walk_normal_001")
    root = encode_angles(motion, angle_feature_spec(motion.skeleton)).values[:, :6]
    forward, sideways, height, yaw_rate, pitch, roll = root.mean(axis=0)
    assert forward > 50 and abs(sideways) < forward / 4
    assert 70 < height < 110
    assert abs(np.degrees(pitch)) < 20 and abs(np.degrees(roll)) < 20  # upright


def test_expmap_and_quaternions_convert_both_ways():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(100, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.sign(q[:, :1])
    np.testing.assert_allclose(expmap_to_quat(quat_to_expmap(q)), q, atol=1e-10)


def test_mirrored_walk_left_moves_right(clip_path):
    motion = body(clip_path, "walk-left_normal_001")
    sideways = encode_positions(motion).control[:, 1].mean()
    mirrored = encode_positions(mirror(motion)).control[:, 1].mean()
    assert sideways > 10  # cm/s to the character's left
    assert mirrored == pytest.approx(-sideways, rel=0.05)


def test_mirroring_swaps_sides_and_twice_is_identity(clip_path):
    motion = body(clip_path, "walk_normal_001")
    pairs = left_right_pairs(motion.skeleton.names)
    assert (motion.skeleton.index("Foot_L"), motion.skeleton.index("Foot_R")) in pairs
    assert len(pairs) == 8
    once = mirror(motion)
    left_hand = motion.skeleton.index("Hand_L")
    right_hand = motion.skeleton.index("Hand_R")
    np.testing.assert_allclose(once.positions[:, right_hand, 0], -motion.positions[:, left_hand, 0])
    np.testing.assert_allclose(mirror(once).positions, motion.positions)


def test_time_reversal_turns_a_walk_into_a_backward_walk(clip_path):
    motion = body(clip_path, "walk_normal_001")
    forward = encode_positions(motion).control[:, 0].mean()
    backward = encode_positions(reverse(motion)).control[:, 0].mean()
    assert forward > 50
    assert backward == pytest.approx(-forward, rel=0.05)
    np.testing.assert_array_equal(reverse(reverse(motion)).positions, motion.positions)


def test_windows_overlap_by_the_hop_and_drop_the_tail():
    frames = np.arange(200).reshape(100, 2)
    w = windows(frames, length=40, hop=20)
    assert w.shape == (4, 40, 2)  # starts 0, 20, 40, 60; 80 would run past the end
    np.testing.assert_array_equal(w[1], frames[20:60])
    assert windows(frames[:30], length=40, hop=20).shape == (0, 40, 2)


def test_resampling_30_to_20_fps_keeps_shared_instants_and_bone_lengths(clip_path):
    original = load_motion(clip_path("walk_normal_001"))
    resampled = resample(original, 20.0)
    assert resampled.fps == 20.0
    assert resampled.n_frames == (original.n_frames - 1) * 2 // 3 + 1
    # t = 0.1 s is frame 3 at 30 fps and frame 2 at 20 fps.
    np.testing.assert_allclose(resampled.positions[::2], original.positions[::3][: len(resampled.positions[::2])], atol=1e-6)
    bones = [(p, j) for j, p in enumerate(original.skeleton.parents) if p >= 1]  # not the sliding joint_Root
    lengths = lambda m: np.stack([np.linalg.norm(m.positions[:, j] - m.positions[:, p], axis=-1) for p, j in bones], 1)
    np.testing.assert_allclose(lengths(resampled), lengths(original)[:1].repeat(resampled.n_frames, 0), atol=1e-6)
    # An in-between frame lies between its neighbours (t = 0.05 s is 1.5 source frames).
    hips = original.skeleton.index("Hips")
    lo, hi = original.positions[1, hips], original.positions[2, hips]
    assert np.all(resampled.positions[1, hips] >= np.minimum(lo, hi) - 0.5)
    assert np.all(resampled.positions[1, hips] <= np.maximum(lo, hi) + 0.5)


def test_position_only_motion_resamples_linearly(clip_path):
    motion = load_motion(clip_path("walk_normal_001"))
    positions_only = type(motion)(motion.positions, motion.fps, motion.skeleton)
    np.testing.assert_allclose(resample(positions_only, 15.0).positions, motion.positions[::2][: resample(positions_only, 15.0).n_frames])


def test_root_is_smooth_and_on_the_floor(clip_path):
    motion = body(clip_path, "walk_normal_001")
    root = root_trajectory(motion)
    hips = motion.positions[:, 0, [0, 2]]
    # The filter removes the hips' side-to-side sway but follows the path.
    assert np.abs(root.xz - hips).max() < 10
    assert np.abs(np.diff(root.xz, 2, axis=0)).max() < np.abs(np.diff(hips, 2, axis=0)).max()
