"""Rotation conversions, vectorised over any leading shape (numpy, float64).

Quaternions are (w, x, y, z) with w first. Euler angles follow the BVH convention:
intrinsic rotations applied in channel order, so channels "Zrotation Xrotation
Yrotation" mean R = Rz(a) @ Rx(b) @ Ry(c).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

AXES = "XYZ"


def axis_rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about one coordinate axis by ``angle`` radians."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(angle), np.zeros_like(angle)
    rows = {
        "X": [[one, zero, zero], [zero, c, -s], [zero, s, c]],
        "Y": [[c, zero, s], [zero, one, zero], [-s, zero, c]],
        "Z": [[c, -s, zero], [s, c, zero], [zero, zero, one]],
    }[axis]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def euler_to_matrix(angles: np.ndarray, order: str) -> np.ndarray:
    """Intrinsic Euler angles (..., len(order)) in radians to matrices (..., 3, 3)."""
    angles = np.asarray(angles, dtype=np.float64)
    result = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for i, axis in enumerate(order):
        result = result @ axis_rotation(axis, angles[..., i])
    return result


def matrix_to_euler(matrix: np.ndarray, order: str) -> np.ndarray:
    """Matrices (..., 3, 3) to intrinsic Euler angles (..., 3) in radians (order of 3 axes)."""
    shape = matrix.shape[:-2]
    flat = Rotation.from_matrix(matrix.reshape(-1, 3, 3)).as_euler(order.upper())
    return flat.reshape(shape + (3,))


def matrix_to_continuous_euler(matrix: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices over time (frames, ..., 3, 3) to intrinsic Euler angles (frames,
    ..., 3) in radians that move continuously from frame to frame.

    Every rotation has two Euler triples, (a, b, c) and (a + pi, pi - b, c + pi), each
    also in whole turns more or less. Each frame takes, of these, the triple nearest the
    previous frame's, so an angle neither wraps at +-180 degrees nor jumps to the other
    triple where the middle angle passes +-90 degrees (a canonical choice of triple
    jumps there); the first frame takes the triple whose middle angle is within +-90.
    """
    first = matrix_to_euler(matrix, order)
    second = first + np.pi * np.array([1.0, 0.0, 1.0])
    second[..., 1] = np.pi - first[..., 1]
    result = np.empty_like(first)
    result[0] = first[0]
    for t in range(1, len(first)):
        candidates = np.stack([first[t], second[t]])
        candidates += 2 * np.pi * np.round((result[t - 1] - candidates) / (2 * np.pi))
        nearest = np.argmin(np.abs(candidates - result[t - 1]).sum(axis=-1), axis=0)
        result[t] = np.take_along_axis(candidates, nearest[None, ..., None], axis=0)[0]
    return result


def matrix_to_quat(matrix: np.ndarray) -> np.ndarray:
    """Matrices (..., 3, 3) to unit quaternions (..., 4), w first, w >= 0."""
    shape = matrix.shape[:-2]
    xyzw = Rotation.from_matrix(matrix.reshape(-1, 3, 3)).as_quat()
    quat = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=-1)
    quat *= np.where(quat[:, :1] < 0, -1.0, 1.0)
    return quat.reshape(shape + (4,))


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4), normalised first, to rotation matrices (..., 3, 3)."""
    q = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def quat_to_expmap(quat: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) to exponential maps (axis * angle, ..., 3)."""
    q = quat * np.where(quat[..., :1] < 0, -1.0, 1.0)  # angle in [0, pi]
    sin_half = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, q[..., :1])
    # angle / sin(angle/2) -> 2 as the angle -> 0; avoid 0/0.
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-12), 2.0)
    return q[..., 1:] * scale


def expmap_to_quat(expmap: np.ndarray) -> np.ndarray:
    """Exponential maps (..., 3) to unit quaternions (..., 4)."""
    angle = np.linalg.norm(expmap, axis=-1, keepdims=True)
    # sin(angle/2) / angle -> 1/2 as the angle -> 0.
    scale = np.where(angle > 1e-12, np.sin(angle / 2) / np.maximum(angle, 1e-12), 0.5)
    return np.concatenate([np.cos(angle / 2), expmap * scale], axis=-1)


def quat_continuity(quat: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip signs along ``axis`` (time) so consecutive quaternions lie in one hemisphere.

    q and -q are the same rotation; without this a network sees jumps that are not in
    the motion.
    """
    q = np.moveaxis(np.array(quat, dtype=np.float64), axis, 0)
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumsum(dots < 0, axis=0) % 2
    q[1:] *= np.where(flips[..., None] == 1, -1.0, 1.0)
    return np.moveaxis(q, 0, axis)


def quat_slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation between unit quaternions (..., 4) with weights t (...)."""
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[..., None] < 0, -q1, q1)  # the short way round
    dot = np.clip(np.abs(dot), -1.0, 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    nearly_equal = sin_theta < 1e-8
    safe = np.where(nearly_equal, 1.0, sin_theta)
    w0 = np.where(nearly_equal, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(nearly_equal, t, np.sin(t * theta) / safe)
    out = w0[..., None] * q0 + w1[..., None] * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def yaw_matrix(yaw: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) about the vertical (y) axis by ``yaw`` radians."""
    return axis_rotation("Y", np.asarray(yaw, dtype=np.float64))
