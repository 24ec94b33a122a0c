"""Inverse kinematics: joint positions back to rotations on the rig, written as rotation
BVH, checked on held-out takes of both real data folders and by an independent reader."""

from __future__ import annotations

import numpy as np
import pytest

from generation.motion import Motion, Skeleton, load_motion, motion_to_bvh, read_bvh, write_bvh
from generation.motion.clip_files import find_bvh_files, load_body_motion, read_labels
from generation.motion.dataset_options import DatasetOptions
from generation.motion.splits import split_takes
from generation.motion.ik import solve_rotations, with_rotations
from generation.motion.kinematics import forward_kinematics
from generation.motion.rotations import euler_to_matrix, matrix_to_continuous_euler, matrix_to_euler, quat_to_matrix

FPS = 20.0  # the models' frame rate
SECONDS = 4.0
# Held-out takes of each folder (the dataset's seeded split): the fastest turns of
# dataset 1 (a punch, a dash), a walk, and runs and turning walks of dataset 2.
TAKES = {
    "motion_data": ("dataset-1_punch_normal_002", "dataset-1_dash_proud_001", "dataset-1_walk_angry_001"),
    "motion_data_2": ("dataset-2_run_normal_001", "dataset-2_walk-turn-left_active_038",
                      "dataset-2_walk-turn-right_elderly_016"),
}
# The targets for positions -> rotations -> forward kinematics (cm).
MEAN_ERROR, WORST_ERROR = 0.5, 2.0
# A joint may turn between two frames at most this much more than the capture's own
# fastest joint did in the same take (degrees): a flip would turn it by up to 180.
TURN_MARGIN = 5.0
# An Euler triple that follows its rotation changes by at most about the turn over the
# cosine of the middle angle (near gimbal lock the outer two angles spin for a small
# turn); a wrap at +-180 degrees or a swap to the other triple jumps far beyond that.
# Measured on every held-out take of both folders: at most 1.08 times.
EULER_RATE = 1.5


def angle_between(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Degrees between unit quaternions (..., 4), whatever their signs."""
    return np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(q0 * q1, axis=-1)), 0.0, 1.0)))


@pytest.fixture(params=[(folder, take) for folder, takes in TAKES.items() for take in takes],
                ids=lambda p: p[1])
def held_out_take(request) -> Motion:
    """The first seconds of a held-out take, as the models see it (body only, at FPS)."""
    folder_fixture, take = request.param
    folder = request.getfixturevalue(folder_fixture)
    files = find_bvh_files(folder)
    options = DatasetOptions()
    held_out = split_takes([(f.stem, read_labels(f)[0]) for f in files], options.holdout_fraction, options.seed)
    assert take in held_out
    motion = load_body_motion(folder / "data" / f"{take}.bvh", FPS)
    frames = int(SECONDS * FPS)
    return Motion(motion.positions[:frames], FPS, motion.skeleton, motion.rotations[:frames],
                  motion.translations[:frames])


def positions_only(motion: Motion) -> Motion:
    return Motion(motion.positions, motion.fps, motion.skeleton)


def test_held_out_takes_come_back_from_rotation_bvh_within_the_targets(held_out_take, tmp_path):
    path = write_bvh(motion_to_bvh(positions_only(held_out_take)), tmp_path / "take.bvh")
    written = read_bvh(path)
    assert written.channels[0][:3] == ("Xposition", "Yposition", "Zposition")
    assert all(names == ("Zrotation", "Xrotation", "Yrotation") for names in written.channels[1:])
    error = np.linalg.norm(load_motion(path).positions - held_out_take.positions, axis=-1)
    assert error.mean() <= MEAN_ERROR and error.max() <= WORST_ERROR


def test_solved_rotations_turn_no_faster_than_the_captured_ones(held_out_take):
    solved = with_rotations(positions_only(held_out_take)).rotations
    fastest_captured = angle_between(held_out_take.rotations[1:], held_out_take.rotations[:-1]).max()
    assert angle_between(solved[1:], solved[:-1]).max() <= fastest_captured + TURN_MARGIN


def test_written_euler_angles_change_only_as_fast_as_their_rotations_turn(held_out_take):
    solved = with_rotations(positions_only(held_out_take))
    bvh = motion_to_bvh(solved)
    rotation = [list(columns)[-3:] for columns in bvh.channel_columns()]  # Z, X, Y of every joint
    euler = bvh.values[:, rotation]  # (frames, joints, 3) degrees
    jumps = np.abs(np.diff(euler, axis=0)).max(axis=-1)
    turns = angle_between(solved.rotations[1:], solved.rotations[:-1])
    cosine = np.minimum(*np.abs(np.cos(np.radians([euler[1:, :, 1], euler[:-1, :, 1]]))))
    assert np.all(jumps <= EULER_RATE * turns / np.maximum(cosine, 1e-3) + 1e-6)


def test_an_independent_reader_agrees_with_the_positions(held_out_take, tmp_path):
    import bvhio  # a dev requirement: a well-kept reader that is not the project's own

    path = write_bvh(motion_to_bvh(positions_only(held_out_take)), tmp_path / "take.bvh")
    root = bvhio.readAsHierarchy(str(path))
    joints = {joint.Name: joint for joint, _, _ in root.layout()}
    frames = range(0, held_out_take.n_frames, 7)
    positions = np.empty((len(frames), held_out_take.skeleton.n_joints, 3))
    for row, frame in enumerate(frames):
        root.loadPose(frame)
        positions[row] = [tuple(joints[name].PositionWorld) for name in held_out_take.skeleton.names]
    # bvhio computes in single precision: agreement to a hundredth of a millimetre
    np.testing.assert_allclose(positions, held_out_take.positions[list(frames)], atol=1e-3)


def _random_motion(skeleton: Skeleton, frames: int, seed: int) -> Motion:
    """Smoothly varying random rotations on ``skeleton`` and the positions they give."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, frames)[:, None, None]
    shape = (1, skeleton.n_joints, 3)
    angles = rng.uniform(-1.5, 1.5, shape) * np.sin(2 * np.pi * t + rng.uniform(0, 6, shape))
    rotations = euler_to_matrix(angles, "ZXY")
    translations = np.broadcast_to(skeleton.offsets, (frames, skeleton.n_joints, 3)).copy()
    translations[:, 0] = rng.normal(size=3) * 10 + t[:, 0] * [50.0, 0.0, 20.0]
    return Motion(forward_kinematics(rotations, translations, skeleton.parents), 30.0, skeleton)


# hips -> {zero-offset lowerback -> chest -> {neck -> head, zero-offset collar -> arm -> hand},
#          zero-offset hip -> thigh -> shin}: zero-offset joints as CMU's rigs have them
CMU_STYLE = Skeleton(
    names=("hips", "lowerback", "chest", "neck", "head", "lclavicle", "lhumerus", "lhand", "lhipjoint", "lfemur",
           "ltibia", "rhipjoint", "rfemur"),
    parents=np.array([-1, 0, 1, 2, 3, 2, 5, 6, 0, 8, 9, 0, 11]),
    offsets=np.array([[0, 90, 0], [0, 0, 0], [0, 20, 0], [0, 15, 0], [0, 10, 0], [0, 0, 0], [15, 0, 0],
                      [25, 0, 0], [0, 0, 0], [8, -5, 0], [0, -40, 0], [0, 0, 0], [-8, -5, 0]], dtype=float),
)
# A rig whose legs point up at rest (the Bandai-Namco rigs' do): every pose of the legs
# is a half turn or so from rest, where a swing from the rest direction is undefined.
LEGS_UP = Skeleton(
    names=("hips", "spine", "head", "thigh_L", "shin_L", "foot_L", "thigh_R", "shin_R"),
    parents=np.array([-1, 0, 1, 0, 3, 4, 0, 6]),
    offsets=np.array([[0, 90, 0], [0, 20, 0], [0, 30, 0], [8, 0, 0], [0, 40, 0], [0, 40, 0], [-8, 0, 0],
                      [0, 40, 0]], dtype=float),
)


@pytest.mark.parametrize("skeleton", [CMU_STYLE, LEGS_UP], ids=["zero-offset joints", "legs up at rest"])
def test_any_rigs_own_motion_comes_back_exactly(skeleton):
    motion = _random_motion(skeleton, 60, seed=3)
    if skeleton is LEGS_UP:  # legs hanging: thigh and shin turned about half a turn from rest
        rotations = quat_to_matrix(solve_rotations(motion.positions, skeleton)[0])
        rotations[:, 3] = euler_to_matrix(np.array([np.pi * 0.95, 0.2, 0.1]), "ZXY") @ rotations[:, 3]
        translations = np.broadcast_to(skeleton.offsets, (60, skeleton.n_joints, 3)).copy()
        translations[:, 0] = motion.positions[:, 0]
        motion = Motion(forward_kinematics(rotations, translations, skeleton.parents), 30.0, skeleton)
    again = with_rotations(motion)
    np.testing.assert_allclose(again.positions, motion.positions, atol=1e-9)
    assert angle_between(again.rotations[1:], again.rotations[:-1]).max() < 45


def test_a_models_stretching_bones_get_the_rigs_lengths_and_keep_their_directions(clip_path):
    take = load_body_motion(clip_path("walk_normal_001"), FPS)
    skeleton = take.skeleton
    rng = np.random.default_rng(0)
    stretched = take.positions + rng.normal(scale=1.5, size=take.positions.shape)  # as a model's bones wobble
    solved = with_rotations(Motion(stretched, FPS, skeleton))
    bones = [(int(p), j) for j, p in enumerate(skeleton.parents) if p >= 0]
    lengths = [np.linalg.norm(solved.positions[:, j] - solved.positions[:, p], axis=-1) for p, j in bones]
    np.testing.assert_allclose(lengths, np.linalg.norm(skeleton.offsets[[j for _, j in bones]], axis=-1)[:, None]
                               * np.ones((1, take.n_frames)), rtol=1e-9)
    np.testing.assert_allclose(solved.positions[:, 0], stretched[:, 0])
    # A joint with one bone (not the hips nor the chest, which fit three) points it exactly.
    for parent, child in bones:
        if np.sum(skeleton.parents == parent) == 1:
            wanted = stretched[:, child] - stretched[:, parent]
            got = solved.positions[:, child] - solved.positions[:, parent]
            cosine = np.sum(wanted * got, -1) / np.linalg.norm(wanted, axis=-1) / np.linalg.norm(got, axis=-1)
            assert cosine.min() > 1 - 1e-9, skeleton.names[child]


def test_positions_that_do_not_fit_the_skeleton_are_refused_naming_both_shapes():
    with pytest.raises(ValueError, match=r"shape \(frames, 13, 3\) for this skeleton, got \(5, 4, 3\)"):
        solve_rotations(np.zeros((5, 4, 3)), CMU_STYLE)


def test_continuous_euler_angles_pass_through_gimbal_lock_and_whole_turns_without_jumping():
    t = np.linspace(0, 4 * np.pi, 400)
    # the middle angle sweeps through +-90 degrees and the first winds round twice
    angles = np.stack([t, 2 * np.sin(t), 0.3 * np.cos(t)], axis=-1)
    matrices = euler_to_matrix(angles, "ZXY")
    canonical = matrix_to_euler(matrices, "ZXY")
    continuous = matrix_to_continuous_euler(matrices, "ZXY")
    assert np.abs(np.diff(canonical, axis=0)).max() > np.pi  # the usual conversion jumps
    assert np.abs(np.diff(continuous, axis=0)).max() < 0.1
    np.testing.assert_allclose(euler_to_matrix(continuous, "ZXY"), matrices, atol=1e-12)


def test_a_bone_that_swings_round_to_near_its_opposite_turns_its_joint_no_faster_than_itself():
    # An arm (one bone, from a fixed shoulder) held mostly along +x that swings over the top
    # to circle 5 degrees off -x: a swing from its usual direction would spin it about itself.
    skeleton = Skeleton(names=("shoulder", "elbow", "hand"), parents=np.array([-1, 0, 1]),
                        offsets=np.array([[0, 100, 0], [0, 10, 0], [10, 0, 0]], dtype=float))
    over = np.linspace(0, np.radians(175), 30)
    around = np.linspace(0, 2 * np.pi, 40)
    directions = np.concatenate([
        np.tile([1.0, 0.0, 0.0], (130, 1)),
        np.stack([np.cos(over), np.sin(over), 0 * over], axis=-1),
        np.stack([-np.cos(np.radians(5)) + 0 * around, np.sin(np.radians(5)) * np.cos(around),
                  np.sin(np.radians(5)) * np.sin(around)], axis=-1),
    ])
    positions = np.zeros((len(directions), 3, 3))
    positions[:, 0] = [0, 100, 0]
    positions[:, 1] = [0, 110, 0]
    positions[:, 2] = positions[:, 1] + 10 * directions
    rotations, _ = solve_rotations(positions, skeleton)
    bone_step = np.degrees(np.arccos(np.clip(np.sum(directions[1:] * directions[:-1], -1), -1, 1)))
    assert np.all(angle_between(rotations[1:, 1], rotations[:-1, 1]) <= 2 * bone_step + 1e-3)
