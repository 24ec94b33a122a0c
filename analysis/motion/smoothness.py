"""Jitter and foot sliding in numbers: what a viewer notices first in a weak model.

Neither is a column of MoGlow's Table 3, but both tell an undertrained model from a good
one before any participant sees it:

* **Mean joint acceleration** (cm/s²): |x_{t+1} − 2 x_t + x_{t−1}| · fps², averaged over
  joints, frames and clips. Natural locomotion at 20 fps scores about 500; noise that
  differs from frame to frame raises it quickly.
* **Lower-foot speed** (cm/s): in each frame, the horizontal speed of whichever foot
  joint is lowest (the one bearing weight), averaged over frames and clips. A planted
  foot hardly moves (natural walking: about 13 cm/s); a character that glides instead of
  stepping moves it at the body's speed. ``generation`` measures it too, so it lives
  below both libraries, in ``measures.feet``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def mean_joint_acceleration(clips: Sequence[np.ndarray], fps: float) -> float:
    """Mean |second difference| · fps² (cm/s²) over every joint, frame and clip (frames, joints, 3)."""
    values = [np.linalg.norm(np.diff(clip, 2, axis=0), axis=-1).ravel() for clip in clips if len(clip) >= 3]
    return float(np.concatenate(values).mean() * fps**2) if values else float("nan")
