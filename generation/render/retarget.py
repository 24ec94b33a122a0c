"""Motion on the study's display figure: each frame's body points placed by the motion's
own bone directions on the figure's bone lengths.

Only directions pass from the motion to the figure, so a taller or shorter performer,
another unit or another rig does not show: the hips keep their place on the floor and
their height scaled by the ratio of the figure's legs to the performer's, and every
other point hangs from its parent point along the direction the motion's joints have
between them, at the figure's length. The figure then stands on the floor as the
performer did (its lowest foot points as high, scaled). Frame rates are resampled to the
study's first (``resample``); the original motion is untouched.
"""

from __future__ import annotations

import numpy as np

from generation.motion.resample import resample
from generation.motion.types import Motion
from generation.render.display_figure import FEET, DisplayFigure, check_mapping, leg_length

# The share of frames whose lowest foot point may be below the floor: a stumble or a
# capture glitch of a frame or two does not lift the whole clip.
FLOOR_QUANTILE = 0.05


def retarget(motion: Motion, mapping: dict[str, str], figure: DisplayFigure, fps: float | None = None) -> Motion:
    """``motion`` (at ``fps`` where given) on ``figure``, its joints mapped to the figure's
    points by ``mapping`` (point -> joint name); MappingError naming the points missing."""
    points = figure.points
    check_mapping(motion.skeleton, mapping, points)
    if fps is not None:
        motion = resample(motion, fps)
    source = motion.positions[:, [motion.skeleton.index(mapping[point]) for point in points]]
    index = {point: j for j, point in enumerate(points)}
    skeleton = figure.skeleton()
    parents, rest = skeleton.parents, skeleton.offsets

    def bone(j: int) -> np.ndarray:
        return source[:, j] - source[:, parents[j]]

    performer_legs = leg_length(lambda point: float(np.median(np.linalg.norm(bone(index[point]), axis=-1))))
    ratio = figure.leg_length / performer_legs if performer_legs > 0 else 1.0
    placed = np.empty_like(source)
    placed[:, 0] = source[:, 0] * np.array([1.0, ratio, 1.0])
    for j in range(1, len(points)):
        vector = bone(j)
        norm = np.linalg.norm(vector, axis=-1, keepdims=True)
        # Two mapped joints at one place (a rig's collapsed bone) keep the figure's rest direction.
        direction = np.where(norm > 1e-9, vector / np.maximum(norm, 1e-12), rest[j] / np.linalg.norm(rest[j]))
        placed[:, j] = placed[:, parents[j]] + figure.lengths[points[j]] * direction
    feet = [index[point] for point in FEET]
    lift = ratio * _floor(source[:, feet]) - _floor(placed[:, feet])
    placed[..., 1] += lift
    return Motion(placed, motion.fps, skeleton)


def _floor(feet: np.ndarray) -> float:
    """How high the feet (T, F, 3) stand: the lowest foot point of most frames."""
    return float(np.quantile(feet[..., 1].min(axis=1), FLOOR_QUANTILE))


__all__ = ["retarget"]
