"""Length units and up axes of motion capture, and the one rule that tells a file's unit.

A BVH file or a motion array states neither its unit nor its up axis. The unit follows
from the size of the figure: from the sole to the head joint (a little less than the
person's height, whatever the pose) a human measures 1.0-2.1 m, and each common unit
puts that length at a different number. The window is narrower than the ratio of any two
units (inches to CMU units, 2.22, is the closest), so at most one unit fits.
``generation`` measures a skeleton at rest, ``analysis`` the figures of its clips; both
ask ``unit_for_height``.

The up axis follows from the figure too: a standing or walking person is taller than
they are long or wide, so along the up axis the figure's extent (its highest joint above
its lowest) is the largest, in most frames. ``up_axis`` takes the median over every
frame; ``generation`` asks it of a BVH file's body, ``analysis`` of its clips' figures.
"""

from __future__ import annotations

import math

import numpy as np

# Centimetres per file unit. "cmu" is the CMU motion-capture database's unit (the ASF
# length 0.45 of an inch: 5.64 cm), in which its BVH conversions are written.
UNITS = {"mm": 0.1, "cm": 1.0, "in": 2.54, "cmu": 2.54 / 0.45, "ft": 30.48, "m": 100.0}
UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "in": "inches", "cmu": "CMU units", "ft": "feet",
              "m": "metres"}
HUMAN_HEIGHT_CM = (100.0, 210.0)  # sole to head joint of a person, standing or walking
UP_AXES = {"y": 1, "z": 2}  # the index of each possible up axis in (x, y, z)
# Rotates a z-up world into the project's y-up one: (x, y, z) -> (x, z, -y).
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def unit_for_height(height: float) -> str | None:
    """The one unit (a key of ``UNITS``) that makes a figure ``height`` file units tall
    human-sized, or None when no unit does."""
    fits = [name for name, factor in UNITS.items() if HUMAN_HEIGHT_CM[0] <= height * factor <= HUMAN_HEIGHT_CM[1]]
    return fits[0] if len(fits) == 1 else None


def up_axis(figures: list[np.ndarray]) -> str:
    """The up axis (a key of ``UP_AXES``) of figures given as joint positions, each an
    array (frames, joints, 3) of the figure's joints only (no reference joint left on the
    floor): the axis along which the figures' extent is largest over all their frames,
    by the median."""
    frames = [np.asarray(figure, dtype=float) for figure in figures]
    if not frames or any(f.ndim != 3 or f.shape[-1] != 3 or f.shape[0] == 0 or f.shape[1] == 0 for f in frames):
        raise ValueError("up_axis needs one or more non-empty (frames, joints, 3) arrays of joint positions")
    extent = {axis: float(np.median(np.concatenate([np.ptp(f[..., i], axis=-1) for f in frames])))
              for axis, i in UP_AXES.items()}
    return max(extent, key=extent.get)


def unit_name(scale: float) -> str:
    """'metres (x100 to cm)' for a known unit's scale, else the bare factor."""
    for key, factor in UNITS.items():
        if math.isclose(scale, factor, rel_tol=1e-9):
            return UNIT_NAMES[key] if key == "cm" else f"{UNIT_NAMES[key]} (x{factor:g} to cm)"
    return f"x{scale:g} to cm"


def parse_scale(text: str) -> float | None:
    """A command line's scale: 'auto' (None), a unit name (m, cm, in, ...) or a factor
    to centimetres; ValueError saying what is accepted otherwise."""
    text = text.strip().lower()
    if text == "auto":
        return None
    if text in UNITS:
        return UNITS[text]
    try:
        scale = float(text)
    except ValueError:
        raise ValueError(f"scale must be auto, a unit ({', '.join(UNITS)}) or a number, got {text!r}") from None
    return check_scale(scale)


def check_scale(scale: float) -> float:
    """``scale`` if it is a positive, finite number of centimetres per file unit; ValueError if not."""
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive number of centimetres per file unit, got {scale}")
    return scale
