"""Forward kinematics, vectorised over frames (a loop over joints only)."""

from __future__ import annotations

import numpy as np

from .rotations import matrix_to_quat, quat_to_matrix
from .types import Motion


def forward_kinematics(
    rotations: np.ndarray, translations: np.ndarray, parents: np.ndarray
) -> np.ndarray:
    """World joint positions (..., J, 3) from local rotation matrices (..., J, 3, 3),
    local translations (..., J, 3) and parent indices (J,), parents before children."""
    global_rot = np.empty_like(rotations)
    positions = np.empty_like(translations)
    for j, p in enumerate(parents):
        if p < 0:
            global_rot[..., j, :, :] = rotations[..., j, :, :]
            positions[..., j, :] = translations[..., j, :]
        else:
            global_rot[..., j, :, :] = global_rot[..., p, :, :] @ rotations[..., j, :, :]
            positions[..., j, :] = positions[..., p, :] + np.einsum(
                "...ab,...b->...a", global_rot[..., p, :, :], translations[..., j, :]
            )
    return positions


def global_rotations(rotations: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """World rotation matrices (..., J, 3, 3) from local ones."""
    result = np.empty_like(rotations)
    for j, p in enumerate(parents):
        result[..., j, :, :] = rotations[..., j, :, :] if p < 0 else result[..., p, :, :] @ rotations[..., j, :, :]
    return result


def subtree_motion(motion: Motion, joint: int) -> Motion:
    """The motion of the joints below (and including) ``joint``, which becomes the root.

    Used to drop reference joints above the hips (a static or sliding "root" node many
    rigs have) so that features describe the body only. The new root's rotation and
    translation are its world ones, so positions are unchanged.
    """
    skeleton, keep = motion.skeleton.subtree(joint)
    if motion.rotations is None:
        return Motion(motion.positions[:, keep], motion.fps, skeleton)
    rotations = motion.rotations[:, keep].copy()
    translations = motion.translations[:, keep].copy()
    world = global_rotations(quat_to_matrix(motion.rotations), motion.skeleton.parents)
    rotations[:, 0] = matrix_to_quat(world[:, joint])
    translations[:, 0] = motion.positions[:, joint]
    return Motion(motion.positions[:, keep], motion.fps, skeleton, rotations, translations)
