"""Joint rotations from joint positions: inverse kinematics on the rig a model learnt.

MoGlow and its path baselines (RNN, VAE) produce joint positions only. Animation tools
want rotations on a skeleton, so this module finds every joint's local rotation on the
model's own rig such that forward kinematics with the rig's offsets (bone lengths exact)
puts each bone along the observed one. Numpy only, vectorised over frames, a loop over
joints.

Derivation
----------
Forward kinematics: joint j with parent p sits at ``x_j = x_p + G_p o_j``, where ``o_j``
is its rest offset (in the parent's axes) and ``G_j = G_p R_j`` its world rotation,
``R_j`` the local rotation a BVH stores. So joint j's rotation is seen only through the
bones hanging from it: for each child c, ``G_j o_c`` must point along ``x_c - x_j``. In
the parent's axes that reads

    R_j r_c = d_c,    r_c = o_c / |o_c|,    d_c = G_p^T (x_c - x_j) / |x_c - x_j|,

solved joint by joint from the root down (G_p is known when j's turn comes; the root's
parent frame is the world). How many independent bone directions hang from j decides
the solver:

* **Two or more** (the hips: spine and legs; the chest: neck and collars): R_j is the
  rotation that carries the rest directions onto the observed ones in the least-squares
  sense (Wahba's problem): with ``B = sum_c d_c r_c^T = U S V^T``,
  ``R_j = U diag(1, 1, det(U V^T)) V^T``. Two non-parallel bones fix it completely, and
  it is unique, so it moves continuously with the pose. On a rig's own motion it is
  exact; on a model's, whose bones stretch, it spreads the disagreement over the bones.
* **One** (a spine or limb segment, the neck): the bone's direction fixes R_j up to a
  twist about the bone, which positions cannot show. It is chosen so that j's axes
  move continuously and stay near a reference.

  Where the single bones below j lead to a joint k of the first kind (the spine's
  segments lead to the chest), j's axes are k's world axes turned the shortest way to
  point j's bone: ``G_j = swing(G_k r -> x) G_k``, x the bone's observed world
  direction. k then bends relative to j without twisting, and the torso's twist
  between hips and chest goes to the segment above the hips.

  Elsewhere (limbs that end in a hand or a foot) the reference is a direction m of the
  bone in the parent's axes: ``R_j = swing(m -> d) Q``, where the fixed Q takes r onto
  m: ``swing(r -> m)`` where the two are less than a right angle apart, else a half
  turn about a normal of r that the rig fixes, then ``swing(-r -> m)``, so that Q does
  not hang on small differences between clips where the rest direction is near
  opposite the usual one (the Bandai-Namco rigs' legs point up at rest). A swing is
  singular where d is opposite its start, and spins the joint about the bone near
  there, so m is the bone's mean direction over the clip, unless the bone comes within
  30 degrees of its opposite; then the one of r and the parent's six axis directions
  that the bone strays least far from. The twist is thus a smooth function of the
  bone's direction, free of the drift that chaining swings from frame to frame
  accumulates.

  ``swing(a -> b)`` is the quaternion ``(1 + a.b, a x b)`` normalised: it turns a onto
  b about their common normal by the angle between them.
* **None** (hands, feet's toes, the head: leaves): nothing observes R_j; it is the
  identity, the joint turning with its parent.

A child with a zero offset (CMU's hip and collar joints) sits on j and shows nothing of
R_j: its own rotation decides where its children go. So j is solved from its other
children; where every child of j sits on it (CMU's hips), R_j is free, and is chosen as
if those children did not turn (their children's rest directions read in j's axes).
Either way each zero-offset child is then solved from its own children, so every bone
still points where it should. A bone that collapses in a frame (two joints on one spot)
leaves that frame's rotation to the other bones, or at the reference. The quaternions
are finally given one sign over time (``quat_continuity``).

The twists positions cannot show need not be the ones a rig's animator chose: on the
Bandai-Namco rigs the spine, the chest and the left leg come out within about ten
degrees of the captured rotations on average, but the right leg (mirrored with a half
turn about its bones) and the arms differ by a twist about their bones. Where every
joint is, and so every bone, is the same.
"""

from __future__ import annotations

import numpy as np

from .kinematics import forward_kinematics
from .rotations import matrix_to_quat, quat_continuity, quat_to_matrix
from .types import Motion, Skeleton

# A rest offset shorter than this (cm) is a joint on its parent's spot, and an observed
# bone shorter than this gives no direction in that frame.
ZERO_LENGTH = 1e-6
# Bones whose rest directions are within about a degree of parallel (the second singular
# value of their unit directions below this) fix no twist between them: one bone.
PARALLEL = 1e-2
# A swing is undefined where the bone points opposite its start, and turns the joint fast
# about the bone near there: a start the bone comes this near the opposite of (cosine of
# 150 degrees) is replaced.
NEAR_OPPOSITE = np.cos(np.radians(150))


def solve_rotations(positions: np.ndarray, skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Local joint rotations (frames, J, 4; unit quaternions, w first, one sign over
    time) and local translations (frames, J, 3: the root's world position, every other
    joint's rest offset) whose forward kinematics follows ``positions`` (frames, J, 3)
    on ``skeleton``: each bone points along the observed one, at the rig's length."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[1:] != (skeleton.n_joints, 3):
        raise ValueError(f"positions must have shape (frames, {skeleton.n_joints}, 3) for this skeleton, "
                         f"got {positions.shape}")
    n_frames, n_joints = positions.shape[:2]
    targets = [_targets(skeleton, j) for j in range(n_joints)]
    directions = [_unit(positions[:, below] - positions[:, j, None]) for j, (below, _) in enumerate(targets)]
    # Joints with two or more independent bones: their world rotations need no parent.
    determined = {j: _wahba(_unit(rest), directions[j]) for j, (_, rest) in enumerate(targets) if _rank(rest) > 1}
    world = np.empty((n_frames, n_joints, 3, 3))
    local = np.empty_like(world)
    for j, p in enumerate(skeleton.parents):
        parent = world[:, p] if p >= 0 else np.broadcast_to(np.eye(3), (n_frames, 3, 3))
        below, rest = targets[j]
        if j in determined:
            world[:, j] = determined[j]
        elif len(below) == 0:
            world[:, j] = parent
        else:  # one bone, or parallel ones: the first stands for all
            bone, observed = _unit(rest[0]), directions[j][:, 0]
            twist_from = _determined_below(below[0], targets, determined)
            if twist_from is not None:
                frame = determined[twist_from]
                world[:, j] = quat_to_matrix(_swing(frame @ bone, observed)) @ frame
            else:
                in_parent = np.einsum("fba,fb->fa", parent, observed)
                world[:, j] = parent @ _swing_from_mean(bone, in_parent)
        local[:, j] = np.swapaxes(parent, -1, -2) @ world[:, j]
    translations = np.broadcast_to(skeleton.offsets, (n_frames, n_joints, 3)).copy()
    translations[:, 0] = positions[:, 0]
    return quat_continuity(matrix_to_quat(local), axis=0), translations


def with_rotations(motion: Motion) -> Motion:
    """``motion`` with joint rotations: itself where it has them, else solved on its
    skeleton (``solve_rotations``), its positions then those of forward kinematics
    (the rig's bone lengths, the root where the motion put it).

    Only the root moves by translation: a rig whose joints below the root are also
    translated (a reference root above animated hips) is solved on its body, the
    hips and below (``kinematics.subtree_motion``), as every model's output is."""
    if motion.rotations is not None:
        return motion
    rotations, translations = solve_rotations(motion.positions, motion.skeleton)
    positions = forward_kinematics(quat_to_matrix(rotations), translations, motion.skeleton.parents)
    return Motion(positions, motion.fps, motion.skeleton, rotations, translations)


def _targets(skeleton: Skeleton, joint: int) -> tuple[list[int], np.ndarray]:
    """The joints whose directions from ``joint`` observe its rotation, and their rest
    offsets in its axes: its children that stand apart from it; where every child sits
    on it, their own targets."""
    children = [int(c) for c in np.flatnonzero(skeleton.parents == joint)]
    apart = [c for c in children if np.linalg.norm(skeleton.offsets[c]) > ZERO_LENGTH]
    if apart or not children:
        return apart, skeleton.offsets[apart].reshape(-1, 3)
    targets, rest = [], []
    for child in children:
        below, offsets = _targets(skeleton, child)
        targets += below
        rest.append(offsets)
    return targets, np.concatenate(rest)


def _rank(rest: np.ndarray) -> int:
    """How many independent directions the rest offsets (targets, 3) span."""
    unit = _unit(rest)
    return int(np.sum(np.linalg.svd(unit, compute_uv=False) > PARALLEL)) if len(rest) else 0


def _determined_below(joint: int, targets: list, determined: dict) -> int | None:
    """The first joint at or below ``joint`` along single bones whose rotation is
    determined (two or more bones hang from it); None where the chain ends in a leaf."""
    while joint not in determined:
        below, rest = targets[joint]
        if not below:
            return None
        joint = below[0]
    return joint


def _wahba(rest: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """The rotations R minimising sum_c |d_c - R r_c|^2 per frame (SVD solution)."""
    b = np.einsum("fti,tj->fij", observed, rest)
    u, _, vt = np.linalg.svd(b)
    diagonal = np.ones((len(b), 3))
    diagonal[:, 2] = np.linalg.det(u @ vt)  # -1 would be a reflection: turn the last axis instead
    return u @ (diagonal[..., None] * vt)


def _swing_from_mean(rest: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """R = swing(m -> d) Q, m where the swings start (``_start_direction``) and Q as
    the module explains."""
    start = _start_direction(rest, observed)
    if np.dot(rest, start) >= 0:
        reference = quat_to_matrix(_swing(rest, start))
    else:  # a half turn about a fixed normal first: the swing left is short, whatever the clip
        half_turn = np.concatenate([[0.0], _normal(rest)])
        reference = quat_to_matrix(_swing(-rest, start)) @ quat_to_matrix(half_turn)
    return quat_to_matrix(_swing(np.broadcast_to(start, observed.shape), observed)) @ reference


def _start_direction(rest: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Where a bone's swings start: its mean direction, unless the bone comes within 30
    degrees of the opposite; then whichever of its rest direction and the parent's six
    axis directions it strays least far from."""
    mean = _unit(observed.mean(axis=0))
    if np.any(mean) and np.min(observed @ mean) > NEAR_OPPOSITE:
        return mean
    candidates = np.concatenate([[rest], np.eye(3), -np.eye(3)])
    return candidates[np.argmax(np.min(observed @ candidates.T, axis=0))]


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) of the shortest rotations taking unit vectors a onto unit
    vectors b (the identity where b is zero; a half turn about a normal of a where b is
    opposite a)."""
    a, b = np.broadcast_arrays(a, b)
    q = np.concatenate([1.0 + np.sum(a * b, axis=-1, keepdims=True), np.cross(a, b)], axis=-1)
    opposite = np.linalg.norm(q, axis=-1) < 1e-9
    if opposite.any():
        q[opposite] = np.concatenate([np.zeros((opposite.sum(), 1)), _normal(a[opposite])], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _normal(a: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit vector in a (..., 3)."""
    least = np.eye(3)[np.argmin(np.abs(a), axis=-1)]  # the axis a leans on least
    return _unit(np.cross(a, least))


def _unit(v: np.ndarray) -> np.ndarray:
    """Vectors scaled to unit length; zero where shorter than ZERO_LENGTH."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(norm > ZERO_LENGTH, v / np.maximum(norm, ZERO_LENGTH), 0.0)
