"""Motion as ``.npz``: the layout ``analysis`` reads for the objective metrics.

Keys: positions (frames, joints, 3) cm; fps; names; parents; offsets (joints, 3); and any
extra arrays given (e.g. ``control`` and ``floor_path``, what a clip was generated for).
``load_motion_npz`` reads it back (offsets optional: the first frame's bones), never
unpickling anything, and holds every array to the rules a BVH file is held to (frame
rate, magnitudes, a root first and parents before their children): the file may come
from another lab's code.
"""

from __future__ import annotations

import io
import os
import zipfile
import zlib
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

import numpy as np

from ..files import write_atomic
from .bvh import MAX_ABS_VALUE, MAX_FRAME_TIME, MIN_FRAME_TIME
from .types import Motion, Skeleton

REQUIRED = ("positions", "fps", "names", "parents")
# What reading one array of the archive can raise on a damaged or hostile file: a broken
# zip member, a malformed .npy header, data shorter than its header says, pickled objects,
# or a declared shape too large to allocate.
ARRAY_READ_ERRORS = (ValueError, OSError, EOFError, zipfile.BadZipFile, zlib.error, MemoryError)
Refuse = Callable[[str | None, str], NoReturn]  # raises MotionFileError for a field
# What the arrays may unpack to: an hour of 120-fps motion on 100 joints is 1 GB. A
# compressed archive of zeros unpacks a thousandfold, so its size alone says little.
MAX_UNPACKED_BYTES = 2 * 1024**3


class MotionFileError(ValueError):
    """A motion ``.npz`` that cannot be read; the message names the file (where known)
    and the array at fault."""

    def __init__(self, file: str | None, field: str | None, message: str):
        where = ": ".join(part for part in (file, field) if part)
        super().__init__(f"{where}: {message}" if where else message)
        self.file, self.field = file, field


def save_motion_npz(motion: Motion, file: str | os.PathLike, **extra: np.ndarray) -> Path:
    """Write a motion (and ``extra`` arrays) atomically."""
    buffer = io.BytesIO()
    np.savez(buffer, positions=motion.positions, fps=np.float64(motion.fps),
             names=np.array(motion.skeleton.names), parents=motion.skeleton.parents,
             offsets=motion.skeleton.offsets, **extra)
    return write_atomic(file, buffer.getvalue())


def load_motion_npz(file: str | os.PathLike | io.BytesIO, name: str | None = None,
                    max_bytes: int = MAX_UNPACKED_BYTES) -> Motion:
    """A motion from the layout above. ``name`` is how messages call the file (default:
    its path; a stream has none, its caller names it). MotionFileError naming the file
    and the array for anything missing or malformed, or arrays that would unpack to more
    than ``max_bytes``."""
    where = name if name is not None else None if isinstance(file, io.IOBase) else str(file)

    def refuse(field: str | None, message: str) -> NoReturn:
        raise MotionFileError(where, field, message)

    try:
        data = np.load(file, allow_pickle=False)
    except FileNotFoundError:
        refuse(None, "no such file")
    except ARRAY_READ_ERRORS as error:  # not a zip, or arrays of Python objects
        refuse(None, f"not a readable .npz file without pickled objects ({error})")
    if not isinstance(data, np.lib.npyio.NpzFile):
        refuse(None, "is a single .npy array, not an .npz of named arrays")
    with data:
        missing = [key for key in REQUIRED if key not in data.files]
        if missing:
            refuse(None, f"lacks the array(s) {', '.join(missing)}")
        unpacked = sum(member.file_size for member in data.zip.infolist())  # as the archive declares, never more
        if unpacked > max_bytes:
            refuse(None, f"its arrays unpack to {unpacked / 1e6:.4g} MB, over the {max_bytes / 1e6:.4g} MB limit")
        arrays = {}
        for key in (*REQUIRED, "offsets"):
            if key in data.files:
                try:
                    arrays[key] = data[key]
                except ARRAY_READ_ERRORS as error:
                    refuse(key, f"cannot be read ({error})")
    names = _names(arrays["names"], refuse)
    parents = _parents(arrays["parents"], names, refuse)
    positions = _lengths(arrays["positions"], "positions", (None, len(names), 3), refuse)
    fps = _fps(arrays["fps"], refuse)
    if "offsets" in arrays:
        offsets = _lengths(arrays["offsets"], "offsets", (len(names), 3), refuse)
    else:
        offsets = positions[0] - np.where(parents[:, None] >= 0, positions[0][np.maximum(parents, 0)], 0.0)
    return Motion(positions, fps, Skeleton(names, parents, offsets))


def _names(array: np.ndarray, refuse: Refuse) -> list[str]:
    if array.dtype.kind != "U":
        refuse("names", f"must be text (the joints' names), got an array of {array.dtype}")
    if array.ndim > 1:
        refuse("names", f"must be one name per joint (a list), got shape {array.shape}")
    names = [str(name) for name in np.atleast_1d(array)]
    if not names:
        refuse("names", "the skeleton has no joints")
    twice = [name for name, count in Counter(names).items() if count > 1]
    if twice:
        refuse("names", f"joint names must be unique; {', '.join(map(repr, twice[:5]))} appear(s) more than once")
    return names


def _parents(array: np.ndarray, names: list[str], refuse: Refuse) -> np.ndarray:
    if array.dtype.kind not in "iu":
        refuse("parents", f"must be whole numbers (each joint's parent index), got an array of {array.dtype}")
    if array.shape != (len(names),):
        refuse("parents", f"must hold one index per joint, shape ({len(names)},) for its {len(names)} names, "
                          f"got {array.shape}")
    parents = array.astype(np.int64)
    for j, parent in enumerate(parents.tolist()):
        if not (parent == -1 if j == 0 else 0 <= parent < j):
            refuse("parents", f"joint {j} ({names[j]!r}) has parent index {parent}; the root comes first (-1) "
                              "and every parent before its children")
    return parents


def _lengths(array: np.ndarray, field: str, shape: tuple[int | None, ...], refuse: Refuse) -> np.ndarray:
    """Centimetres of ``shape`` (None: any length of at least one), finite and of a size a body can have."""
    wanted = "(" + ", ".join("frames" if n is None else str(n) for n in shape) + ")"
    if array.dtype.kind not in "biuf":
        refuse(field, f"must be numbers, got an array of {array.dtype}")
    if array.ndim != len(shape) or any(n is not None and n != got for n, got in zip(shape, array.shape)):
        refuse(field, f"must have shape {wanted}, got {array.shape}")
    if array.size == 0 and None in shape:
        refuse(field, "has no frames; a motion needs at least one")
    values = array.astype(np.float64)
    if not np.isfinite(values).all():
        index = np.argwhere(~np.isfinite(values))[0][:-1]  # the frame and joint, or the joint
        at = ", ".join(f"{axis} {int(i)}" for axis, i in zip(("frame", "joint")[-len(index):], index))
        refuse(field, f"holds NaN or infinity (first at {at})")
    if not (np.abs(values) <= MAX_ABS_VALUE).all():
        refuse(field, f"holds a value beyond ±{MAX_ABS_VALUE:g} cm")
    return values


def _fps(array: np.ndarray, refuse: Refuse) -> float:
    low, high = 1 / MAX_FRAME_TIME, 1 / MIN_FRAME_TIME
    if array.dtype.kind not in "iuf" or array.size != 1:
        refuse("fps", f"must be one number of frames per second, got {array.dtype} of shape {array.shape}")
    fps = float(array.reshape(()))
    if not low <= fps <= high:  # NaN fails too
        refuse("fps", f"{fps:g} is outside {low:g} to {high:g} frames per second")
    return fps
