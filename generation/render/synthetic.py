"""A hand-made stick figure walking in a circle, so renderer tests and benchmarks need no data.

Not a motion model: just enough limbs (named with _L/_R so the side colours show) swinging
in a plausible rhythm while the pelvis travels round a circle on the floor.
"""

from __future__ import annotations

import numpy as np

from generation.motion.types import Motion, Skeleton

# name, parent, rest offset from the parent (cm, y up, facing +z)
_JOINTS = (
    ("Hips", -1, (0, 90, 0)),
    ("Spine", 0, (0, 25, 0)),
    ("Neck", 1, (0, 30, 0)),
    ("Head", 2, (0, 15, 0)),
    ("Shoulder_L", 2, (18, -5, 0)),
    ("Hand_L", 4, (0, -55, 0)),
    ("Shoulder_R", 2, (-18, -5, 0)),
    ("Hand_R", 6, (0, -55, 0)),
    ("UpLeg_L", 0, (10, 0, 0)),
    ("Foot_L", 8, (0, -85, 0)),
    ("UpLeg_R", 0, (-10, 0, 0)),
    ("Foot_R", 10, (0, -85, 0)),
)

SKELETON = Skeleton(
    names=tuple(name for name, _, _ in _JOINTS),
    parents=np.array([parent for _, parent, _ in _JOINTS]),
    offsets=np.array([offset for _, _, offset in _JOINTS], dtype=np.float64),
)


def walking_in_a_circle(
    seconds: float = 4.0, fps: float = 30.0, radius: float = 200.0, speed: float = 120.0
) -> Motion:
    """A figure walking anticlockwise (seen from above) round a circle centred at the origin."""
    t = np.arange(int(round(seconds * fps))) / fps
    heading = speed * t / radius  # radians travelled round the circle
    swing = np.sin(2 * np.pi * 0.9 * t)  # one stride per leg every ~1.1 s

    # Positions in the walker's own frame (x left, y up, z forward), then placed on the circle.
    local = np.zeros((len(t), len(_JOINTS), 3))
    for j, parent in enumerate(SKELETON.parents):
        local[:, j] = (local[:, parent] if parent >= 0 else 0) + SKELETON.offsets[j]
    for foot, leg, sign in (("Foot_L", "UpLeg_L", 1), ("Foot_R", "UpLeg_R", -1)):
        angle = 0.4 * sign * swing
        f, l = SKELETON.index(foot), SKELETON.index(leg)
        local[:, f] = local[:, l] + 85 * np.stack([0 * t, -np.cos(angle), np.sin(angle)], axis=1)
    for hand, shoulder, sign in (("Hand_L", "Shoulder_L", -1), ("Hand_R", "Shoulder_R", 1)):
        angle = 0.3 * sign * swing
        h, s = SKELETON.index(hand), SKELETON.index(shoulder)
        local[:, h] = local[:, s] + 55 * np.stack([0 * t, -np.cos(angle), np.sin(angle)], axis=1)

    # Walking anticlockwise seen from above (+y): forward is the circle's tangent.
    forward = np.stack([np.cos(heading), 0 * t, -np.sin(heading)], axis=1)
    left = np.stack([-np.sin(heading), 0 * t, -np.cos(heading)], axis=1)
    centre = radius * np.stack([np.sin(heading), 0 * t, np.cos(heading)], axis=1)
    positions = (
        centre[:, None]
        + local[..., :1] * left[:, None]
        + local[..., 1:2] * np.array([0.0, 1.0, 0.0])
        + local[..., 2:] * forward[:, None]
    )
    return Motion(positions=positions, fps=fps, skeleton=SKELETON)
