"""BVH reading and writing, forward kinematics, and errors on malformed files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from generation.motion import BVHError, load_motion, motion_to_bvh, read_bvh, write_bvh

SMALL_BVH = """HIERARCHY
ROOT pelvis
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
\tJOINT spine
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Yrotation Zrotation Xrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
    JOINT leg
    {
        OFFSET 3 -2 1
        CHANNELS 3 Zrotation Yrotation Xrotation
        End Site
        {
            OFFSET 0 -8 0
        }
    }
}
MOTION
Frames: 3
Frame Time: 0.008333333
1 90 2 10 20 30 5 6 7 40 50 60
1.5 91 2 11 21 31 6 7 8 41 51 61
2 92 2 -12 22 -32 7 8 9 42 -52 62
"""


def naive_positions(bvh, frame: int) -> np.ndarray:
    """Forward kinematics joint by joint with scipy's rotations: an independent check."""
    skeleton, row = bvh.skeleton, bvh.values[frame]
    world_rot, world_pos, col = [], [], 0
    for j, names in enumerate(bvh.channels):
        values = dict(zip(names, row[col : col + len(names)]))
        col += len(names)
        order = "".join(n[0] for n in names if n.endswith("rotation"))
        local = Rotation.from_euler(order.upper(), [values[f"{a}rotation"] for a in order], degrees=True)
        offset = np.array([values.get(f"{a}position", skeleton.offsets[j][i]) for i, a in enumerate("XYZ")])
        p = skeleton.parents[j]
        if p < 0:
            world_rot.append(local)
            world_pos.append(offset)
        else:
            world_rot.append(world_rot[p] * local)
            world_pos.append(world_pos[p] + world_rot[p].apply(offset))
    return np.array(world_pos)


@pytest.fixture
def small_bvh(tmp_path: Path) -> Path:
    path = tmp_path / "small.bvh"
    path.write_text(SMALL_BVH)
    return path


def test_small_file_with_tabs_spaces_end_sites_and_mixed_orders_is_parsed(small_bvh):
    bvh = read_bvh(small_bvh)
    assert bvh.skeleton.names == ("pelvis", "spine", "leg")
    assert bvh.skeleton.parents.tolist() == [-1, 0, 0]
    assert bvh.channels[1] == ("Yrotation", "Zrotation", "Xrotation")
    assert set(bvh.skeleton.end_sites) == {1, 2}
    assert bvh.fps == 120.0
    assert bvh.values.shape == (3, 12)


def test_forward_kinematics_matches_scipy_on_a_small_file(small_bvh):
    bvh = read_bvh(small_bvh)
    motion = bvh.to_motion()
    for frame in range(3):
        np.testing.assert_allclose(motion.positions[frame], naive_positions(bvh, frame), atol=1e-9)


def test_forward_kinematics_matches_scipy_on_real_clips(clip_path):
    for name in ("walk_normal_001", "run_happy_002", "bow_angry_001"):
        path = clip_path(name)
        if not path.exists():
            path = clip_path(name.replace("_002", "_001"))
        bvh = read_bvh(path)
        motion = bvh.to_motion()
        for frame in (0, len(bvh.values) // 2, len(bvh.values) - 1):
            np.testing.assert_allclose(motion.positions[frame], naive_positions(bvh, frame), atol=1e-6)


def test_real_clip_round_trips_through_the_writer(clip_path, tmp_path):
    original = read_bvh(clip_path("walk-left_normal_001"))
    copy = read_bvh(write_bvh(original, tmp_path / "copy.bvh"))
    assert copy.skeleton.names == original.skeleton.names
    np.testing.assert_array_equal(copy.skeleton.parents, original.skeleton.parents)
    np.testing.assert_allclose(copy.skeleton.offsets, original.skeleton.offsets, rtol=1e-8)
    assert copy.channels == original.channels
    assert copy.frame_time == pytest.approx(original.frame_time)
    np.testing.assert_allclose(copy.values, original.values, rtol=1e-8, atol=1e-12)


def test_motion_with_rotations_converts_back_to_an_equivalent_bvh(clip_path, tmp_path):
    motion = load_motion(clip_path("dash_normal_001"))
    again = read_bvh(write_bvh(motion_to_bvh(motion, "YXZ"), tmp_path / "again.bvh")).to_motion()
    np.testing.assert_allclose(again.positions, motion.positions, atol=1e-4)


def test_real_motion_is_centimetres_and_y_up(clip_path):
    motion = load_motion(clip_path("walk_normal_001"))
    head = motion.positions[:, motion.skeleton.index("Head")]
    toes = motion.positions[:, motion.skeleton.index("Toes_L")]
    assert 120 < head[:, 1].mean() < 190  # an adult's head height in cm
    assert toes[:, 1].min() > -5


BAD_FILES = {
    "truncated": (lambda t: t.rsplit("\n", 2)[0] + "\n", "truncated", 29),
    "wrong count": (lambda t: t.replace("1.5 91 2 11 21 31 6 7 8 41 51 61", "1.5 91 2 11 21 31 6 7 8 41 51"),
                    "needs 12 numbers, found 11", 29),
    "non-numeric": (lambda t: t.replace("92 2 -12", "92 abc -12"), "non-numeric", 30),
    "zero frames": (lambda t: t.split("Frames: 3")[0] + "Frames: 0\nFrame Time: 0.01\n", "0 frames", None),
    "unknown channel": (lambda t: t.replace("Yrotation Zrotation Xrotation", "Yrotation Zrotation Wrotation"),
                        "unknown channel name 'Wrotation'", 9),
    "nan": (lambda t: t.replace("1 90 2", "1 nan 2"), "NaN", 28),
    "unclosed": (lambda t: t.replace("}\nMOTION", "MOTION"), "blocks are closed", 24),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_malformed_files_raise_an_error_naming_file_and_line(tmp_path, case):
    corrupt, message, line = BAD_FILES[case]
    path = tmp_path / "bad.bvh"
    path.write_text(corrupt(SMALL_BVH))
    with pytest.raises(BVHError) as error:
        read_bvh(path)
    assert message in str(error.value)
    assert str(path) in str(error.value)
    if line is not None:
        assert error.value.line == line, str(error.value)


def test_a_failed_write_leaves_no_partial_file(small_bvh, tmp_path, monkeypatch):
    import generation.files as files_module

    def fail_to_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(files_module.os, "replace", fail_to_replace)
    with pytest.raises(OSError, match="disk full"):
        write_bvh(read_bvh(small_bvh), tmp_path / "clip.bvh")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["small.bvh"]


def test_position_only_motion_writes_a_rotation_bvh_that_reproduces_its_positions(clip_path, tmp_path):
    from generation.motion import Motion
    from generation.motion.clip_files import load_body_motion

    motion = load_body_motion(clip_path("walk_normal_001"), 30.0)  # the body, as models give it
    positions_only = Motion(motion.positions, motion.fps, motion.skeleton)
    written = read_bvh(write_bvh(motion_to_bvh(positions_only), tmp_path / "positions.bvh"))
    assert [len(names) for names in written.channels] == [6] + [3] * (motion.skeleton.n_joints - 1)
    np.testing.assert_allclose(written.to_motion().positions, motion.positions, atol=1e-4)


@pytest.mark.parametrize("unit", ["m", "in"])
@pytest.mark.parametrize("kind", ["rotations", "positions only"])
def test_motion_written_in_another_unit_reads_back_as_the_same_centimetres_with_the_unit_detected(
        clip_path, tmp_path, unit, kind):
    from generation.motion import Motion
    from generation.motion.clip_files import load_body_motion
    from generation.motion.unit_detection import choose_units
    from generation.motion.skeleton_units import Units
    from measures.units import UNITS

    motion = load_body_motion(clip_path("walk_normal_001"), 30.0)
    if kind == "positions only":  # as MoGlow and its baselines write it
        motion = Motion(motion.positions, motion.fps, motion.skeleton)
    path = write_bvh(motion_to_bvh(motion, unit=unit), tmp_path / f"{unit}.bvh")
    written = read_bvh(path)
    np.testing.assert_allclose(written.skeleton.offsets * UNITS[unit], motion.skeleton.offsets, atol=1e-6)
    units = choose_units([path]).units
    assert units == Units(UNITS[unit], "y")
    again = load_motion(path, units.scale, units.up)
    np.testing.assert_allclose(again.positions, motion.positions, atol=1e-4)


def test_an_unknown_bvh_unit_is_refused_naming_the_known_ones(clip_path):
    with pytest.raises(ValueError, match=r"BVH unit must be one of mm, cm, in, cmu, ft, m, got 'yards'"):
        motion_to_bvh(load_motion(clip_path("walk_normal_001")), unit="yards")
