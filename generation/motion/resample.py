"""Changing a motion's frame rate (MoGlow works at 20 fps)."""

from __future__ import annotations

import numpy as np

from .kinematics import forward_kinematics
from .rotations import quat_slerp, quat_to_matrix
from .types import Motion

DEFAULT_FPS = 20.0


def resample(motion: Motion, fps: float = DEFAULT_FPS) -> Motion:
    """The motion at ``fps``, sampled at t = k / fps over the original's time span.

    Joint rotations are interpolated by slerp and positions recomputed by forward
    kinematics, so bone lengths stay exact; position-only motions are interpolated
    linearly.
    """
    if not fps > 0:
        raise ValueError(f"target fps must be positive, got {fps}")
    if fps == motion.fps:
        return motion
    n_new = int(np.floor((motion.n_frames - 1) * fps / motion.fps + 1e-9)) + 1
    source = np.arange(n_new) * (motion.fps / fps)
    lo = np.minimum(np.floor(source).astype(int), motion.n_frames - 1)
    hi = np.minimum(lo + 1, motion.n_frames - 1)
    w = source - lo

    def lerp(a: np.ndarray) -> np.ndarray:
        weight = w.reshape((-1,) + (1,) * (a.ndim - 1))
        return (1 - weight) * a[lo] + weight * a[hi]

    if motion.rotations is None:
        return Motion(lerp(motion.positions), fps, motion.skeleton)
    rotations = quat_slerp(motion.rotations[lo], motion.rotations[hi], w[:, None])
    translations = lerp(motion.translations)
    positions = forward_kinematics(quat_to_matrix(rotations), translations, motion.skeleton.parents)
    return Motion(positions, fps, motion.skeleton, rotations, translations)
