"""Length units and up axes of motion capture, and the conversion to centimetres, y up.

A BVH file states neither its unit nor its up axis. The unit follows from the size of
the skeleton: the chain from the tip of a foot through the hips to the head
(``skeleton_size``) measures 1.2-2.1 m in an adult human (it leaves out the skull
above the head joint, so it is a little less than the person's height whatever the
pose), and each common unit puts a human rig in that range at a different number, so at
most one unit fits. The up axis follows from the floor: along it the hips stay high
above the lowest joint of the body (a foot on the floor) all the time; along a
horizontal axis they do not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .root import hips_index
from .symmetry import left_right_pairs
from .types import Motion, Skeleton

# Centimetres per file unit. "cmu" is the CMU motion-capture database's unit (the ASF
# length 0.45 of an inch: 5.64 cm), in which its BVH conversions are written.
UNITS = {"mm": 0.1, "cm": 1.0, "in": 2.54, "cmu": 2.54 / 0.45, "ft": 30.48, "m": 100.0}
UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "in": "inches", "cmu": "CMU units", "ft": "feet",
              "m": "metres"}
HUMAN_SIZE_CM = (120.0, 210.0)  # ``skeleton_size`` of an adult, 1.4-2.1 m tall
UP_AXES = ("y", "z")
# Rotates a z-up world into the project's y-up one: (x, y, z) -> (x, z, -y).
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class Units:
    """How a file's lengths and axes map to the project's: lengths times ``scale`` are
    centimetres, and ``up`` is the file's vertical axis."""

    scale: float = 1.0
    up: str = "y"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be a positive number of centimetres per file unit, got {self.scale}")
        if self.up not in UP_AXES:
            raise ValueError(f"up axis must be one of {', '.join(UP_AXES)}, got {self.up!r}")

    def describe(self) -> str:
        return f"{unit_name(self.scale)}, {self.up} up"


def unit_name(scale: float) -> str:
    """'metres (x100 to cm)' for a known unit's scale, else the bare factor."""
    for key, factor in UNITS.items():
        if math.isclose(scale, factor, rel_tol=1e-9):
            return UNIT_NAMES[key] if key == "cm" else f"{UNIT_NAMES[key]} (x{factor:g} to cm)"
    return f"x{scale:g} to cm"


def parse_scale(text: str) -> float | None:
    """A command-line scale: 'auto' (None), a unit name (m, cm, in, ...) or a factor to cm."""
    text = text.strip().lower()
    if text == "auto":
        return None
    if text in UNITS:
        return UNITS[text]
    try:
        scale = float(text)
    except ValueError:
        raise ValueError(f"scale must be auto, a unit ({', '.join(UNITS)}) or a number, got {text!r}") from None
    Units(scale=scale)  # validates
    return scale


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


def unit_for_size(size: float) -> str | None:
    """The one unit that makes a skeleton of ``size`` file units human-sized, or None."""
    fits = [name for name, factor in UNITS.items()
            if HUMAN_SIZE_CM[0] <= size * factor <= HUMAN_SIZE_CM[1]]
    return fits[0] if len(fits) == 1 else None


def detect_up(motion: Motion, hips: str | None = None) -> str:
    """The file's up axis: the one along which the hips stand highest above the body's
    lowest joint, in the median frame."""
    h = hips_index(motion.skeleton, hips)
    _, body = motion.skeleton.subtree(h)
    positions = motion.positions[:, body]
    hips_height = {
        axis: float(np.median(positions[:, 0, i] - positions[:, :, i].min(axis=1)))
        for axis, i in (("y", 1), ("z", 2))
    }
    return max(hips_height, key=hips_height.get)
