"""Contact sheets: n evenly spaced frames side by side in one PNG.

For papers, study pages and a quick look at a clip without a video player. Uses the same
``FrameDrawer`` as the videos, so a sheet shows exactly what participants see.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image

from generation.motion.types import Motion
from generation.render.camera import Camera
from generation.render.draw import FrameDrawer
from generation.files import atomic_output
from generation.render.style import Style


def contact_sheet(
    motion: Motion,
    path: str | os.PathLike,
    n: int = 8,
    camera: Camera = Camera(),
    size: tuple[int, int] = (320, 240),
    root_path: np.ndarray | None = None,
    style: Style = Style(),
    control_path: np.ndarray | None = None,
) -> Path:
    """Write a PNG strip of ``n`` frames (each ``size``), first to last, and return the path;
    ``root_path`` and ``control_path`` as in ``render_video``."""
    if n < 1:
        raise ValueError(f"n must be at least 1, got {n}")
    drawer = FrameDrawer(motion, camera, size, None, root_path, style, control_path)
    picks = np.linspace(0, len(drawer) - 1, n).round().astype(int)
    width, height = drawer.size
    sheet = Image.new("RGB", (width * n, height), style.background)
    for i, k in enumerate(picks.tolist()):
        sheet.paste(drawer.image(k), (i * width, 0))
    path = Path(path)
    with atomic_output(path) as tmp:
        sheet.save(tmp, format="PNG")
    return path
