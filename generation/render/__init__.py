"""Stick-figure rendering of motion for perceptual studies: MP4 stimuli and contact sheets.

    from generation.render import Camera, Style, render_video, contact_sheet
    render_video(motion, "clip.mp4", camera=Camera(azimuth=60), size=(640, 480), fps=20)
    render_video(motion, "asked.mp4", control_path=control.path().xz)  # the path it was asked for

One ``Camera`` and one ``Style`` per study (both serialise with ``to_dict``/``from_dict``)
so every system is drawn identically.
"""

from generation.render.camera import Camera
from generation.render.draw import FrameDrawer
from generation.render.sheet import contact_sheet
from generation.render.style import Style
from generation.render.video import render_video

__all__ = ["Camera", "FrameDrawer", "Style", "contact_sheet", "render_video"]
