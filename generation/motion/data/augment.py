"""Data augmentation (mirroring, time reversal) and fixed-length windows."""

from __future__ import annotations

import numpy as np

from ..symmetry import left_right_pairs, mirror_permutation
from ..types import Motion

MIRROR = np.array([-1.0, 1.0, 1.0])  # reflect through the world's x = 0 plane


def mirror(motion: Motion, pairs: dict[str, str] | None = None) -> Motion:
    """The motion reflected left to right, with left and right joints swapped.

    ``pairs`` overrides the left/right joint pairing found from names. The result has
    positions only: reflecting local joint frames depends on how a rig orients them,
    so mirrored clips feed the position-based models (MoGlow and its baselines).
    """
    order = mirror_permutation(motion.skeleton.n_joints, left_right_pairs(motion.skeleton.names, pairs))
    return Motion(motion.positions[:, order] * MIRROR, motion.fps, motion.skeleton)


def reverse(motion: Motion) -> Motion:
    """The motion played backwards."""
    flip = (lambda a: None if a is None else a[::-1].copy())
    return Motion(
        motion.positions[::-1].copy(), motion.fps, motion.skeleton,
        flip(motion.rotations), flip(motion.translations),
    )


def window_count(frames: int, length: int, hop: int) -> int:
    """How many windows ``windows`` cuts from a clip of ``frames`` frames."""
    return 0 if frames < length else (frames - length) // hop + 1


def windows(frames: np.ndarray, length: int, hop: int) -> np.ndarray:
    """Overlapping windows (n, length, ...) of a (frames, ...) array; the tail that does
    not fill a whole window is dropped, and a clip shorter than one window gives none."""
    if length < 1 or hop < 1:
        raise ValueError(f"window length and hop must be at least 1, got {length} and {hop}")
    if len(frames) < length:
        return np.empty((0, length) + frames.shape[1:], dtype=frames.dtype)
    starts = np.arange(window_count(len(frames), length, hop)) * hop
    return np.stack([frames[s : s + length] for s in starts])
