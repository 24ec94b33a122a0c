"""The two motion representations the models learn from, each with its exact inverse.

* Position features (MoGlow): the pose is every joint's position in the root's
  floor-level frame, flattened to (frames, 3 * joints); the control is the root's
  (forward, sideways, yaw) velocity (frames, 3). Decoding integrates the control and
  places the pose back in the world.
* Angle features (HVRNN, ERD, QuaterNet): six root values (forward and sideways
  velocity, hips height, yaw rate, pitch and roll relative to the facing direction)
  followed by the local rotation of every joint below the hips, as unit quaternions or
  exponential maps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinematics import forward_kinematics, global_rotations
from .root import (
    RootOptions,
    RootTrajectory,
    hips_index,
    integrate,
    limb_root_pairs,
    root_trajectory,
    velocities,
)
from .rotations import (
    euler_to_matrix,
    expmap_to_quat,
    matrix_to_euler,
    matrix_to_quat,
    quat_continuity,
    quat_to_expmap,
    quat_to_matrix,
    yaw_matrix,
)
from .symmetry import left_right_pairs
from .types import Motion, Skeleton

CONTROL_NAMES = ("forward velocity (cm/s)", "sideways velocity, left positive (cm/s)", "yaw rate (rad/s)")


@dataclass(frozen=True)
class PositionFeatures:
    """MoGlow's representation of one clip."""

    pose: np.ndarray  # (frames, 3 * joints) joint positions in the root frame, cm
    control: np.ndarray  # (frames, 3) forward, sideways, yaw velocity
    root: RootTrajectory  # where the root was, to place a decoded clip back in the world


def encode_positions(motion: Motion, options: RootOptions = RootOptions()) -> PositionFeatures:
    """MoGlow features of a motion."""
    root = root_trajectory(motion, options)
    centred = motion.positions.copy()
    centred[..., 0] -= root.xz[:, None, 0]
    centred[..., 2] -= root.xz[:, None, 1]
    # Rotate world vectors into the root frame: v_local = R(yaw)^T v_world.
    local = np.einsum("tba,tjb->tja", yaw_matrix(root.yaw), centred)
    pose = local.reshape(len(local), -1)
    return PositionFeatures(pose=pose, control=velocities(root.xz, root.yaw, motion.fps), root=root)


def decode_positions(
    pose: np.ndarray,
    control: np.ndarray,
    fps: float,
    start_xz: np.ndarray | None = None,
    start_yaw: float = 0.0,
) -> np.ndarray:
    """World joint positions (frames, joints, 3) from pose features and integrated control."""
    root = integrate(control, fps, start_xz, start_yaw)
    local = pose.reshape(len(pose), -1, 3)
    world = np.einsum("tab,tjb->tja", yaw_matrix(root.yaw), local)
    world[..., 0] += root.xz[:, None, 0]
    world[..., 2] += root.xz[:, None, 1]
    return world


# Angle features start with six root values: forward and sideways velocity, hips height,
# yaw rate, pitch, roll; each joint's rotation follows.
ROOT_DIMS = 6


@dataclass(frozen=True)
class AngleFeatureSpec:
    """Everything needed to turn angle features back into a motion on a skeleton."""

    representation: str  # "quaternion" or "expmap"
    hips: int
    joints: tuple[int, ...]  # the joints whose local rotations follow the root values
    alignment: np.ndarray  # (3, 3) maps the canonical (left, up, forward) frame into the hips frame

    @property
    def size(self) -> int:
        return 6 + len(self.joints) * (4 if self.representation == "quaternion" else 3)

    def to_dict(self) -> dict:
        return {
            "representation": self.representation,
            "hips": self.hips,
            "joints": list(self.joints),
            "alignment": self.alignment.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> "AngleFeatureSpec":
        return cls(data["representation"], int(data["hips"]), tuple(data["joints"]), np.asarray(data["alignment"]))


def angle_feature_spec(skeleton: Skeleton, representation: str = "quaternion", hips: str | None = None,
                       pairs: dict[str, str] | None = None) -> AngleFeatureSpec:
    """The angle-feature layout for a skeleton (``pairs``: left/right joints, as in ``RootOptions``)."""
    if representation not in ("quaternion", "expmap"):
        raise ValueError(f"unknown rotation representation {representation!r}; use 'quaternion' or 'expmap'")
    h = hips_index(skeleton, hips)
    below = [j for j in range(skeleton.n_joints) if _descends_from(skeleton, j, h) and j != h]
    return AngleFeatureSpec(representation, h, tuple(below), hips_alignment(skeleton, h, pairs))


def _descends_from(skeleton: Skeleton, j: int, ancestor: int) -> bool:
    while j >= 0:
        if j == ancestor:
            return True
        j = int(skeleton.parents[j])
    return False


def hips_alignment(skeleton: Skeleton, hips: int, pairs: dict[str, str] | None = None) -> np.ndarray:
    """The canonical body frame (columns: left, up, forward) in the hips' local axes.

    Rigs disagree on which local axis of the hips points up or forward; the rest pose
    below the hips tells: the legs' across vector gives left, the spine gives up. The
    spine's first joints may sit on the hips (CMU's ``lowerback`` has ``OFFSET 0 0 0``),
    so "up" points to the first joint up the spine that stands apart from them.
    """
    sided = {j for pair in left_right_pairs(skeleton.names, pairs) for j in pair}
    legs = [(l, r) for l, r in limb_root_pairs(skeleton, pairs) if _limb_base(skeleton, l, sided) == hips]
    spine = _spine(skeleton, hips, sided)
    if not legs or not spine:
        raise ValueError(
            f"cannot align the hips {skeleton.names[hips]!r}: it needs a spine and a pair of legs below it "
            f"(left/right joints found: {', '.join(skeleton.names[j] for j in sorted(sided)) or 'none'})"
        )
    rest = _rest_below(skeleton, hips)
    left = sum(rest[l] - rest[r] for l, r in legs)
    left = left / np.linalg.norm(left)
    size = max(float(np.linalg.norm(skeleton.offsets, axis=-1).max()), 1e-12)
    for joint in spine:
        up = rest[joint] - np.dot(rest[joint], left) * left
        if np.linalg.norm(up) > 1e-6 * size:
            up = up / np.linalg.norm(up)
            return np.column_stack([left, up, np.cross(left, up)])
    raise ValueError(
        f"cannot align the hips {skeleton.names[hips]!r}: no joint of its spine "
        f"({', '.join(skeleton.names[j] for j in spine)}) stands above it at rest (their offsets are zero "
        "or point sideways), so the rig gives no up direction"
    )


def _spine(skeleton: Skeleton, hips: int, sided: set[int]) -> list[int]:
    """The chain up from the hips through the first child that belongs to neither side."""
    chain, joint = [], hips
    while True:
        joint = next((j for j in range(skeleton.n_joints) if skeleton.parents[j] == joint and j not in sided), None)
        if joint is None:
            return chain
        chain.append(joint)


def _limb_base(skeleton: Skeleton, j: int, sided: set[int]) -> int:
    """The first ancestor of joint j that belongs to neither side: where its limb hangs."""
    while j in sided:
        j = int(skeleton.parents[j])
    return j


def _rest_below(skeleton: Skeleton, joint: int) -> np.ndarray:
    """Rest positions (J, 3) relative to ``joint`` of the joints below it (others: zero)."""
    rest = np.zeros((skeleton.n_joints, 3))
    for j in range(joint + 1, skeleton.n_joints):
        if _descends_from(skeleton, j, joint):
            p = int(skeleton.parents[j])
            rest[j] = skeleton.offsets[j] if p == joint else rest[p] + skeleton.offsets[j]
    return rest


@dataclass(frozen=True)
class AngleFeatures:
    """HVRNN's representation of one clip."""

    values: np.ndarray  # (frames, spec.size): six root values, then joint rotations
    root: RootTrajectory  # the hips' floor position and heading, to place a decoded clip


def encode_angles(motion: Motion, spec: AngleFeatureSpec) -> AngleFeatures:
    """Angle features of a motion that has joint rotations."""
    if motion.rotations is None:
        raise ValueError("angle features need joint rotations; this motion has positions only")
    local = quat_to_matrix(motion.rotations)
    hips_world = global_rotations(local, motion.skeleton.parents)[:, spec.hips] @ spec.alignment
    yaw, pitch, roll = np.moveaxis(matrix_to_euler(hips_world, "YXZ"), -1, 0)
    yaw = np.unwrap(yaw)
    hips = motion.positions[:, spec.hips]
    vel = velocities(hips[:, [0, 2]], yaw, motion.fps)
    root = np.column_stack([vel[:, 0], vel[:, 1], hips[:, 1], vel[:, 2], pitch, roll])
    quats = quat_continuity(motion.rotations[:, list(spec.joints)], axis=0)
    joints = quats if spec.representation == "quaternion" else quat_to_expmap(quats)
    values = np.concatenate([root, joints.reshape(len(joints), -1)], axis=1)
    return AngleFeatures(values, RootTrajectory(xz=hips[:, [0, 2]], yaw=yaw))


def decode_angles(
    features: np.ndarray,
    skeleton: Skeleton,
    spec: AngleFeatureSpec,
    fps: float,
    start_xz: np.ndarray | None = None,
    start_yaw: float = 0.0,
) -> Motion:
    """A motion from angle features; the joints above the hips are held at rest."""
    n = len(features)
    fwd, side, height, yaw_rate, pitch, roll = features[:, :6].T
    root = integrate(np.column_stack([fwd, side, yaw_rate]), fps, start_xz, start_yaw)
    width = 4 if spec.representation == "quaternion" else 3
    joints = features[:, 6:].reshape(n, len(spec.joints), width)
    quats = joints if spec.representation == "quaternion" else expmap_to_quat(joints)

    rotations = np.broadcast_to(np.eye(3), (n, skeleton.n_joints, 3, 3)).copy()
    rotations[:, list(spec.joints)] = quat_to_matrix(quats)
    translations = np.broadcast_to(skeleton.offsets, (n, skeleton.n_joints, 3)).copy()
    # Joints above the hips are at rest (identity rotations), so the hips' local
    # rotation and translation are their world ones, less the ancestors' offsets.
    hips_world = euler_to_matrix(np.column_stack([root.yaw, pitch, roll]), "YXZ") @ spec.alignment.T
    rotations[:, spec.hips] = hips_world
    ancestors_offset = np.zeros(3)
    j = int(skeleton.parents[spec.hips])
    while j >= 0:
        ancestors_offset += skeleton.offsets[j]
        j = int(skeleton.parents[j])
    translations[:, spec.hips] = np.column_stack([root.xz[:, 0], height, root.xz[:, 1]]) - ancestors_offset
    positions = forward_kinematics(rotations, translations, skeleton.parents)
    return Motion(positions, fps, skeleton, matrix_to_quat(rotations), translations)
