"""Motion as ``.npz``: the layout ``analysis`` reads for the objective metrics.

Keys: positions (frames, joints, 3) cm; fps; names; parents; offsets (joints, 3); and any
extra arrays given (e.g. ``control`` and ``floor_path``, what a clip was generated for).
``load_motion_npz`` reads it back (offsets optional: the first frame's bones), never
unpickling anything.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from ..files import write_atomic
from .types import Motion, Skeleton


def save_motion_npz(motion: Motion, file: str | os.PathLike, **extra: np.ndarray) -> Path:
    """Write a motion (and ``extra`` arrays) atomically."""
    buffer = io.BytesIO()
    np.savez(buffer, positions=motion.positions, fps=np.float64(motion.fps),
             names=np.array(motion.skeleton.names), parents=motion.skeleton.parents,
             offsets=motion.skeleton.offsets, **extra)
    return write_atomic(file, buffer.getvalue())


def load_motion_npz(file: str | os.PathLike | io.BytesIO) -> Motion:
    """A motion from the layout above; ValueError saying what is missing or malformed."""
    try:
        data = np.load(file, allow_pickle=False)
    except (OSError, ValueError) as error:  # not a zip, or arrays of Python objects
        raise ValueError(f"not a readable .npz file without pickled objects ({error})") from None
    with data:
        missing = [key for key in ("positions", "fps", "names", "parents") if key not in data.files]
        if missing:
            raise ValueError(f"lacks the array(s) {', '.join(missing)}")
        positions = np.asarray(data["positions"], dtype=np.float64)
        names = [str(name) for name in np.atleast_1d(data["names"])]
        parents = np.asarray(data["parents"], dtype=np.int64)
        if positions.ndim != 3 or positions.shape[1:] != (len(names), 3):
            raise ValueError(f"positions must be (frames, {len(names)}, 3) for its {len(names)} names, "
                             f"got {positions.shape}")
        if data["fps"].size != 1:
            raise ValueError(f"fps must be one number, got shape {data['fps'].shape}")
        fps = float(data["fps"])
        if "offsets" in data.files:
            offsets = np.asarray(data["offsets"], dtype=np.float64)
        else:
            offsets = positions[0] - np.where(parents[:, None] >= 0, positions[0][np.maximum(parents, 0)], 0.0)
    return Motion(positions, fps, Skeleton(names, parents, offsets))
