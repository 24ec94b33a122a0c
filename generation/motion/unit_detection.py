"""The unit and up axis of a set of BVH files: given, or detected (``units``) and checked
to be the same for every file."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from measures.units import HUMAN_HEIGHT_CM, UNITS, unit_for_height

from .bvh import load_motion, read_bvh_skeleton
from .root import RootOptions
from .skeleton_units import Units, detect_up, skeleton_size


@dataclass(frozen=True)
class UnitChoice:
    """The units chosen for some files, and a line for the user saying how."""

    units: Units
    description: str


def choose_units(files: list[Path], scale: float | None = None, up: str | None = None,
                 root: RootOptions = RootOptions()) -> UnitChoice:
    """``scale`` and ``up`` as given, or detected where None: the unit from every file's
    skeleton (all must agree; a folder mixing units is an error naming the outliers),
    the up axis from the first file's motion."""
    if not files:
        raise ValueError("no BVH files to choose units for")
    how = []
    if scale is None:
        scale, said = _detect_scale(files, root)
        how.append(said)
    else:
        how.append("scale given")
    if up is None:
        up = detect_up(load_motion(files[0], scale), root.hips)
        how.append(f"up axis detected from {files[0].name}")
    else:
        how.append("up axis given")
    units = Units(scale, up)
    return UnitChoice(units, f"motion units: {units.describe()} ({'; '.join(how)})")


def _detect_scale(files: list[Path], root: RootOptions) -> tuple[float, str]:
    sizes, units = {}, {}
    for path in files:
        skeleton = read_bvh_skeleton(path)
        try:
            sizes[path] = skeleton_size(skeleton, root.hips, root.pairs)
        except ValueError as error:
            raise ValueError(f"{path}: {error}") from None
        units[path] = unit_for_height(sizes[path])
    counts = Counter(units.values())
    unit, _ = counts.most_common(1)[0]
    outliers = [p for p in files if units[p] != unit]
    if outliers:
        example = next(p for p in files if units[p] == unit)
        listed = ", ".join(f"{p.name} ({sizes[p]:.4g} units: {units[p] or 'no common unit'})" for p in outliers[:10])
        more = f" and {len(outliers) - 10} more" if len(outliers) > 10 else ""
        raise ValueError(
            f"the files mix units: {counts[unit]} are in {unit or 'no common unit'} (such as {example.name}, "
            f"{sizes[example]:.4g} units from foot to head), but not {listed}{more}; "
            "convert them, or give the scale (--scale) to read them all alike"
        )
    size = float(np.median(list(sizes.values())))
    if unit is None:
        return 1.0, (f"the skeleton measures {size:.4g} units from foot to head, which no common unit "
                     f"makes human-sized ({HUMAN_HEIGHT_CM[0]:g}-{HUMAN_HEIGHT_CM[1]:g} cm): assumed centimetres, "
                     "give --scale otherwise")
    return UNITS[unit], f"unit detected from the skeleton's size, {size:.4g} {unit} from foot to head"
