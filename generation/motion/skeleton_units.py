"""The unit and up axis of a BVH file's skeleton and motion, and their conversion to
centimetres, y up.

A BVH file states neither its unit nor its up axis. The unit follows from the size of
the skeleton: the chain from the tip of a foot through the hips to the head
(``skeleton_size``) is a little less than the person's height whatever the pose, and
``measures.units.unit_for_height`` (the rule ``analysis`` reads motion arrays by) names
the one unit that makes it a human's. The up axis is the one along which the body
stands tallest, by the same rule ``analysis`` reads motion arrays by
(``measures.units.up_axis``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from measures.units import UP_AXES, check_scale, unit_name, up_axis

from .root import hips_index
from .symmetry import left_right_pairs
from .types import Motion, Skeleton


@dataclass(frozen=True)
class Units:
    """How a file's lengths and axes map to the project's: lengths times ``scale`` are
    centimetres, and ``up`` is the file's vertical axis."""

    scale: float = 1.0
    up: str = "y"

    def __post_init__(self) -> None:
        check_scale(self.scale)
        if self.up not in UP_AXES:
            raise ValueError(f"up axis must be one of {', '.join(UP_AXES)}, got {self.up!r}")

    def describe(self) -> str:
        return f"{unit_name(self.scale)}, {self.up} up"


def skeleton_size(skeleton: Skeleton, hips: str | None = None, pairs: dict[str, str] | None = None) -> float:
    """Length of the longest leg (hips to the tip of a foot) plus the spine (hips to the
    end of the head), in the skeleton's unit: how tall the character stands, whatever
    its pose or the orientation of its joints' local axes.

    Legs are left/right limbs hanging from the hips; the spine is the chain of joints
    above the hips that belong to neither side.
    """
    h = hips_index(skeleton, hips)
    sided = {j for pair in left_right_pairs(skeleton.names, pairs) for j in pair}
    length = np.linalg.norm(skeleton.offsets, axis=-1)
    reach = {h: 0.0}  # path length from the hips
    limb = {h: "spine"}
    leg = spine = 0.0
    for j in range(h, skeleton.n_joints):
        p = int(skeleton.parents[j])
        if j != h:
            if p not in reach:
                continue
            reach[j] = reach[p] + length[j]
            limb[j] = ("leg" if j in sided else "spine") if p == h else limb[p]
            if limb[j] == "spine" and j in sided:
                limb[j] = "arm"
        sites = skeleton.end_sites.get(j)
        tip = reach[j] + (float(np.linalg.norm(sites, axis=-1).max()) if sites is not None and len(sites) else 0.0)
        if limb[j] == "leg":
            leg = max(leg, tip)
        elif limb[j] == "spine":
            spine = max(spine, tip)
    if leg == 0.0:
        raise ValueError(
            f"cannot measure the skeleton: no left/right legs below the hips {skeleton.names[h]!r} "
            "(name them with _L/_R, Left/Right, ... or give the scale)"
        )
    return leg + spine


def detect_up(motion: Motion, hips: str | None = None) -> str:
    """The file's up axis: the one along which the body (the hips and every joint below
    them, so no reference joint on the floor) stands tallest (``measures.units.up_axis``)."""
    _, body = motion.skeleton.subtree(hips_index(motion.skeleton, hips))
    return up_axis([motion.positions[:, body]])
