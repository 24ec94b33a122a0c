"""Hostile motion ``.npz`` files (another lab's submitted motion): each is refused with an
error naming the file and the array at fault, never an IndexError from deep in the motion
code, and a real clip still reads back as it was written.
"""

from __future__ import annotations

import io

import numpy as np
import pytest

from generation.motion.bvh import load_motion
from generation.motion.npz import MotionFileError, load_motion_npz, save_motion_npz
from generation.motion.types import Skeleton

THREE_JOINTS = {"positions": np.zeros((5, 3, 3)), "fps": np.float64(20.0), "names": np.array(["hips", "spine", "head"]),
                "parents": np.array([-1, 0, 1]), "offsets": np.zeros((3, 3))}


def npz_bytes(**arrays) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def changed(drop: tuple[str, ...] = (), **arrays) -> dict:
    return {key: value for key, value in {**THREE_JOINTS, **arrays}.items() if key not in drop}


HOSTILE_NPZ = {
    "parents [-1, 7, 99] without offsets": (changed(("offsets",), parents=np.array([-1, 7, 99])), "parents",
                                            "joint 1 ('spine') has parent index 7"),
    "no joints": (changed(positions=np.zeros((5, 0, 3)), names=np.array([], dtype=str),
                          parents=np.array([], dtype=np.int64), offsets=np.zeros((0, 3))), "names",
                  "the skeleton has no joints"),
    "a root that has a parent": (changed(parents=np.array([0, 0, 1])), "parents", "joint 0 ('hips') has parent index 0"),
    "fractional parents": (changed(parents=np.array([-1.0, 0.5, 1.0])), "parents", "must be whole numbers"),
    "one parent too few": (changed(parents=np.array([-1, 0])), "parents", "shape (3,) for its 3 names, got (2,)"),
    "names as numbers": (changed(names=np.array([1, 2, 3])), "names", "must be text"),
    "a name twice": (changed(names=np.array(["hips", "hips", "head"])), "names", "'hips' appear(s) more than once"),
    "positions of no frames": (changed(positions=np.zeros((0, 3, 3))), "positions", "has no frames"),
    "positions of text": (changed(positions=np.full((5, 3, 3), "x")), "positions", "must be numbers"),
    "positions in 2-D": (changed(positions=np.zeros((5, 3))), "positions", "must have shape (frames, 3, 3)"),
    "a NaN position": (changed(positions=np.where(np.arange(45).reshape(5, 3, 3) == 10, np.nan, 0.0)), "positions",
                       "NaN or infinity (first at frame 1, joint 0)"),
    "a position of 1e300": (changed(positions=np.full((5, 3, 3), 1e300)), "positions", "beyond ±1e+09 cm"),
    "offsets of the wrong shape": (changed(offsets=np.zeros((2, 3))), "offsets", "must have shape (3, 3)"),
    "fps 0": (changed(fps=np.float64(0.0)), "fps", "0 is outside 0.1 to 10000 frames per second"),
    "fps nan": (changed(fps=np.float64(np.nan)), "fps", "nan is outside"),
    "fps as text": (changed(fps=np.array("20")), "fps", "must be one number of frames per second"),
    "two fps": (changed(fps=np.array([20.0, 30.0])), "fps", "must be one number"),
    "no parents": (changed(("parents",)), None, "lacks the array(s) parents"),
}


@pytest.mark.parametrize("arrays, field, message", HOSTILE_NPZ.values(), ids=HOSTILE_NPZ.keys())
def test_a_hostile_npz_is_refused_naming_the_file_and_the_array(arrays, field, message, tmp_path):
    path = tmp_path / "clip.npz"
    path.write_bytes(npz_bytes(**arrays))
    with pytest.raises(MotionFileError) as caught:
        load_motion_npz(path)
    assert str(caught.value).startswith(f"{path}: {field}: " if field else f"{path}: ")
    assert message in str(caught.value)
    assert caught.value.field == field


def test_a_stream_is_named_by_its_caller_or_not_at_all():
    data = npz_bytes(**changed(("offsets",), parents=np.array([-1, 7, 99])))
    with pytest.raises(MotionFileError, match=r"^lab/c1\.npz: parents: joint 1"):
        load_motion_npz(io.BytesIO(data), name="lab/c1.npz")
    with pytest.raises(MotionFileError, match=r"^parents: joint 1"):
        load_motion_npz(io.BytesIO(data))


@pytest.mark.parametrize("content, message", [
    (b"", "not a readable .npz file"),
    (b"PK\x03\x04 not really a zip", "not a readable .npz file"),
    (None, "is a single .npy array, not an .npz of named arrays"),
])
def test_a_file_that_is_no_npz_archive_is_refused_naming_it(content, message, tmp_path):
    path = tmp_path / "clip.npz"
    if content is None:
        np.save(path.with_suffix(".npy"), np.zeros(3))
        path.with_suffix(".npy").rename(path)
    else:
        path.write_bytes(content)
    with pytest.raises(MotionFileError, match=f"^{path}: {message}"):
        load_motion_npz(path)
    with pytest.raises(MotionFileError, match=f"^{tmp_path / 'missing.npz'}: no such file"):
        load_motion_npz(tmp_path / "missing.npz")


def test_an_npz_that_unpacks_past_the_limit_is_refused_before_its_arrays_are_read():
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **changed(positions=np.zeros((20_000, 3, 3))))  # 1.4 MB of zeros, a few kB packed
    assert len(buffer.getvalue()) < 20_000
    with pytest.raises(MotionFileError, match=r"^lab/c1\.npz: its arrays unpack to 1\.441 MB, over the 1 MB limit"):
        load_motion_npz(io.BytesIO(buffer.getvalue()), name="lab/c1.npz", max_bytes=1_000_000)
    assert load_motion_npz(io.BytesIO(buffer.getvalue())).n_frames == 20_000


def test_a_skeleton_without_joints_is_refused_where_it_is_made():
    with pytest.raises(ValueError, match="a skeleton needs at least one joint, its root"):
        Skeleton((), np.zeros(0, dtype=np.int64), np.zeros((0, 3)))


def test_a_real_clip_reads_back_as_written_with_or_without_offsets(clip_path, tmp_path):
    motion = load_motion(clip_path("walk_normal_001"))
    path = save_motion_npz(motion, tmp_path / "walk.npz")
    again = load_motion_npz(path)
    assert again.skeleton.names == motion.skeleton.names and again.fps == motion.fps
    assert np.array_equal(again.positions, motion.positions)
    assert np.array_equal(again.skeleton.parents, motion.skeleton.parents)
    with np.load(path) as data:
        without = {key: data[key] for key in data.files if key != "offsets"}
    bones = load_motion_npz(io.BytesIO(npz_bytes(**without))).skeleton.offsets
    child, parent = 5, int(motion.skeleton.parents[5])
    assert np.allclose(bones[child], motion.positions[0, child] - motion.positions[0, parent])
