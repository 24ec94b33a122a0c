"""Motion as ``.npz``: the layout ``analysis`` reads for the objective metrics.

Keys: positions (frames, joints, 3) cm; fps; names; parents; offsets (joints, 3); and any
extra arrays given (e.g. ``control`` and ``floor_path``, what a clip was generated for).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from ..files import write_atomic
from .types import Motion


def save_motion_npz(motion: Motion, file: str | os.PathLike, **extra: np.ndarray) -> Path:
    """Write a motion (and ``extra`` arrays) atomically."""
    buffer = io.BytesIO()
    np.savez(buffer, positions=motion.positions, fps=np.float64(motion.fps),
             names=np.array(motion.skeleton.names), parents=motion.skeleton.parents,
             offsets=motion.skeleton.offsets, **extra)
    return write_atomic(file, buffer.getvalue())
