"""The character's root on the floor: a smoothed position and facing (yaw) over time.

Both MoGlow's and HVRNN's representations express the pose relative to this root and
describe the root's motion as velocities in its own frame, so that the models see the
same thing wherever the character stands and whichever way it faces.

Axes: y is up; yaw 0 faces +z; in the root frame +z is forward and +x is the
character's left.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from .symmetry import left_right_pairs
from .types import Motion, Skeleton


@dataclass(frozen=True)
class RootOptions:
    """How the root is found and smoothed. Sigmas are in seconds."""

    hips: str | None = None  # default: the first joint named like hips or pelvis
    position_sigma: float = 0.1
    facing_sigma: float = 0.25
    # Left -> right joint names whose across vectors give the facing, for rigs whose
    # names follow no common convention; default: found from the names (``symmetry``).
    pairs: dict[str, str] | None = None


def hips_index(skeleton: Skeleton, name: str | None = None) -> int:
    """The joint that carries the body: ``name``, else one named hips/pelvis, else the root."""
    if name is not None:
        return skeleton.index(name)
    for j, joint in enumerate(skeleton.names):
        if re.search(r"hip|pelvis", joint, re.IGNORECASE) and not _is_sided(skeleton, j):
            return j
    return 0


def _is_sided(skeleton: Skeleton, j: int) -> bool:
    return any(j in pair for pair in left_right_pairs(skeleton.names))


def limb_root_pairs(skeleton: Skeleton, pairs: dict[str, str] | None = None) -> list[tuple[int, int]]:
    """The first left/right pairs of each pair of limbs (upper legs, shoulders or upper
    arms) that stand apart at rest: their difference vectors point to the character's
    left and define its facing.

    A limb starts at a left/right pair with a common parent; where that pair sits at the
    same place (the zero-offset hip and collar joints of CMU-style rigs) the pair of
    their children is taken instead, and so on down the limb. ``pairs`` overrides the
    pairing found from names.
    """
    sides = dict(left_right_pairs(skeleton.names, pairs))
    rest = _rest_positions(skeleton)
    size = max(float(np.linalg.norm(skeleton.offsets, axis=-1).max()), 1e-12)
    found = []
    starts = [(l, r) for l, r in sides.items() if skeleton.parents[l] == skeleton.parents[r]]
    while starts:
        l, r = starts.pop()
        if np.linalg.norm(rest[l] - rest[r]) > 1e-6 * size:
            found.append((l, r))
            continue
        children = {c for c in range(skeleton.n_joints) if skeleton.parents[c] == r}
        starts += [(cl, cr) for cl, cr in sides.items() if skeleton.parents[cl] == l and cr in children]
    if not found:
        raise ValueError(
            "cannot find the facing direction: no left/right joints that stand apart "
            f"(joints: {', '.join(skeleton.names)}); name them with _L/_R, Left/Right, ... "
            "or give the pairs explicitly (--mirror-pairs LEFT:RIGHT,...)"
        )
    return sorted(found)


def _rest_positions(skeleton: Skeleton) -> np.ndarray:
    """Joint positions (J, 3) in the rest pose (every rotation the identity)."""
    rest = np.zeros((skeleton.n_joints, 3))
    for j, p in enumerate(skeleton.parents):
        rest[j] = skeleton.offsets[j] + (rest[p] if p >= 0 else 0.0)
    return rest


def facing_directions(positions: np.ndarray, skeleton: Skeleton, pairs: dict[str, str] | None = None) -> np.ndarray:
    """Unfiltered horizontal unit forward vectors (frames, 3) from the across vectors."""
    across = sum(positions[:, l] - positions[:, r] for l, r in limb_root_pairs(skeleton, pairs))
    forward = np.cross(across, np.array([0.0, 1.0, 0.0]))
    forward[:, 1] = 0.0
    norm = np.linalg.norm(forward, axis=-1, keepdims=True)
    return forward / np.maximum(norm, 1e-9)


@dataclass(frozen=True)
class RootTrajectory:
    """The smoothed root: floor position (frames, 2) as (x, z) and unwrapped yaw (frames,)."""

    xz: np.ndarray
    yaw: np.ndarray


def root_trajectory(motion: Motion, options: RootOptions = RootOptions()) -> RootTrajectory:
    """Gaussian-filtered floor projection of the hips, and the filtered facing angle."""
    hips = motion.positions[:, hips_index(motion.skeleton, options.hips)]
    xz = gaussian_filter1d(hips[:, [0, 2]], options.position_sigma * motion.fps, axis=0, mode="nearest")
    forward = gaussian_filter1d(
        facing_directions(motion.positions, motion.skeleton, options.pairs),
        options.facing_sigma * motion.fps, axis=0, mode="nearest",
    )
    yaw = np.unwrap(np.arctan2(forward[:, 0], forward[:, 2]))
    return RootTrajectory(xz=xz, yaw=yaw)


def to_root_frame(vectors_xz: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World floor vectors (..., 2) as (x, z) into root frames of the given yaw: (side, forward)."""
    c, s = np.cos(yaw), np.sin(yaw)
    x, z = vectors_xz[..., 0], vectors_xz[..., 1]
    return np.stack([c * x - s * z, s * x + c * z], axis=-1)


def from_root_frame(local: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Inverse of ``to_root_frame``: (side, forward) in the root frame to world (x, z)."""
    c, s = np.cos(yaw), np.sin(yaw)
    side, fwd = local[..., 0], local[..., 1]
    return np.stack([c * side + s * fwd, -s * side + c * fwd], axis=-1)


def velocities(xz: np.ndarray, yaw: np.ndarray, fps: float) -> np.ndarray:
    """Per-frame (forward, sideways, yaw) velocities (frames, 3) in cm/s and rad/s.

    Frame t holds the motion from t-1 to t, expressed in the root frame at t-1, so that
    integration (``integrate``) is exact; frame 0 repeats frame 1.
    """
    if len(xz) < 2:
        return np.zeros((len(xz), 3))
    step = to_root_frame(np.diff(xz, axis=0), yaw[:-1]) * fps
    vel = np.column_stack([step[:, 1], step[:, 0], np.diff(yaw) * fps])
    return np.vstack([vel[:1], vel])


def integrate(
    control: np.ndarray, fps: float, start_xz: np.ndarray | None = None, start_yaw: float = 0.0
) -> RootTrajectory:
    """The root trajectory from (forward, sideways, yaw) velocities; inverse of ``velocities``."""
    yaw = start_yaw + np.concatenate([[0.0], np.cumsum(control[1:, 2]) / fps])
    local = np.column_stack([control[1:, 1], control[1:, 0]]) / fps
    steps = from_root_frame(local, yaw[:-1])
    start = np.zeros(2) if start_xz is None else np.asarray(start_xz, dtype=np.float64)
    xz = start + np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    return RootTrajectory(xz=xz, yaw=yaw)
