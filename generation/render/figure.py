"""Which parts of a skeleton make up the drawn figure.

A BVH skeleton often has a reference joint above the pelvis (e.g. ``joint_Root`` pinned
at the world origin). Drawing its bone would paint a long line from the origin to the
walking character, and following it would keep the camera still, so the renderer works
from the *body root*: the pelvis if the skeleton names one, else joint 0.
"""

from __future__ import annotations

from generation.motion.symmetry import left_right_pairs
from generation.motion.types import Skeleton

BODY_ROOT_NAMES = ("hips", "pelvis", "hip")

LEFT, CENTRE, RIGHT = -1, 0, 1


def body_root_index(skeleton: Skeleton) -> int:
    """The joint whose floor projection is the character's path (pelvis, else joint 0)."""
    lowered = [name.lower() for name in skeleton.names]
    for candidate in BODY_ROOT_NAMES:
        if candidate in lowered:
            return lowered.index(candidate)
    return 0


def figure_bones(skeleton: Skeleton) -> list[tuple[int, int]]:
    """(parent, child) bones to draw: all but those hanging from the body root's ancestors."""
    hidden = hidden_joints(skeleton)
    return [(p, c) for p, c in skeleton.bones() if p not in hidden]


def hidden_joints(skeleton: Skeleton) -> set[int]:
    """The body root's proper ancestors: reference joints that are not part of the body."""
    hidden = set()
    j = int(skeleton.parents[body_root_index(skeleton)])
    while j >= 0:
        hidden.add(j)
        j = int(skeleton.parents[j])
    return hidden


def joint_sides(skeleton: Skeleton) -> list[int]:
    """LEFT, RIGHT or CENTRE for every joint: the sides of its left/right pair, paired
    from the names as mirroring pairs them (``generation.motion.symmetry``)."""
    sides = [CENTRE] * skeleton.n_joints
    for left, right in left_right_pairs(skeleton.names):
        sides[left], sides[right] = LEFT, RIGHT
    return sides
