"""Motion arrays in other units or with z up, brought to the centimetres and y up that
the metrics are stated in (footstep tolerances in cm/s, bone errors in cm).

Given, or detected from the clips: the up axis is the one along which the figures
stand tallest (``measures.units.up_axis``, the rule ``generation`` reads BVH files by),
and the unit the one common unit that makes that height a human's
(``measures.units.unit_for_height``, the rule ``generation`` reads BVH files by), clip
by clip: clips that different units make human-sized are an error naming them.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import numpy as np

from analysis.errors import AnalysisInputError
from analysis.motion.motion_io import SystemClips
from measures.units import HUMAN_HEIGHT_CM, UNITS, UP_AXES, Z_UP_TO_Y_UP, unit_for_height, up_axis


def to_centimetres_y_up(motion: dict[str, SystemClips], scale: float | None = None,
                        up: str | None = None) -> tuple[dict[str, SystemClips], str]:
    """Every system's clips (and offsets) in cm with y up, and a line saying what the
    input was taken to be. ``scale`` (cm per unit) and ``up`` are detected where None."""
    if up is not None and up not in UP_AXES:
        raise AnalysisInputError(f"--up must be auto, y or z, got {up!r}")
    how = f"scale {'detected' if scale is None else 'given'}, up axis {'detected' if up is None else 'given'}"
    if up is None:
        up = up_axis([clip[:, _figure(system)] for system in motion.values() for clip in system.clips])
    if scale is None:
        scale = _detect_scale(motion, UP_AXES[up])
    rotation = Z_UP_TO_Y_UP if up == "z" else np.eye(3)
    if scale == 1.0 and up == "y":
        converted = motion
    else:
        converted = {
            name: replace(system, clips=[clip @ rotation.T * scale for clip in system.clips],
                          offsets=None if system.offsets is None else system.offsets * scale)
            for name, system in motion.items()
        }
    unit = next((name for name, factor in UNITS.items() if np.isclose(factor, scale)), f"x{scale:g} cm")
    return converted, f"motion units: {unit}, {up} up ({how})"


def _detect_scale(motion: dict[str, SystemClips], axis: int) -> float:
    """The one unit that makes the clips' figures human-sized. Each clip is measured on
    its own: clips that another unit would make human-sized are an error naming them (a
    folder mixing units), while a clip that no unit makes human-sized is measured in the
    others' unit (a crumpled or stretched figure is what the metrics are there to show)."""
    height, unit = {}, {}
    for system in motion.values():
        for k, frames in enumerate(_heights(system, axis)):
            source = system.source(k)
            height[source] = float(np.median(frames))
            unit[source] = unit_for_height(height[source])
    counts = Counter(u for u in unit.values() if u is not None)
    if not counts:
        raise AnalysisInputError(
            f"cannot tell the unit of the motion: the figures stand {np.median(list(height.values())):.4g} units "
            f"tall, which no common unit makes human-sized ({HUMAN_HEIGHT_CM[0]:g}-{HUMAN_HEIGHT_CM[1]:g} cm); "
            "give --scale")
    common, count = counts.most_common(1)[0]
    outliers = [source for source, u in unit.items() if u not in (None, common)]
    if outliers:
        example = next(source for source, u in unit.items() if u == common)
        listed = ", ".join(f"{s} ({height[s]:.4g} units: {unit[s]})" for s in outliers[:10])
        more = f" and {len(outliers) - 10} more" if len(outliers) > 10 else ""
        raise AnalysisInputError(
            f"the clips mix units: {count} are in {common} (such as {example}, {height[example]:.4g} units tall), "
            f"but not {listed}{more}; convert them, or give --scale to read them all alike")
    return UNITS[common]


def _figure(system: SystemClips) -> list[int]:
    """The joints of the figure. A root joint with a single child is a reference on the
    floor that stays behind as the figure walks off (as in the Bandai-Namco rig), not
    part of the figure."""
    parents = np.asarray(system.parents)
    root = int(np.flatnonzero(parents < 0)[0])
    return [j for j in range(len(parents)) if not (j == root and (parents == root).sum() == 1)]


def _heights(system: SystemClips, axis: int) -> list[np.ndarray]:
    """Per clip, the figure's extent along ``axis`` in every frame."""
    figure = _figure(system)
    return [np.ptp(clip[:, figure, axis], axis=-1) for clip in system.clips]
