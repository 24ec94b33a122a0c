"""The device check's clip: a neutral test clip that is no study's stimulus.

The device check plays a video before the participant has consented, so it must not be
one of the study's clips (that would show a stimulus, and which systems are rated, to
someone who has not agreed to take part). It plays the hand-made stick figure of
``generation.render.synthetic`` instead, drawn by the study renderer: rendered once into
the app's static files (``python -m studyapp.participants.device_clip`` renders it again)
and served like the pages' scripts, so every study's device check shows the same clip.
"""

from __future__ import annotations

from pathlib import Path

from django.templatetags.static import static

from generation.render.synthetic import walking_in_a_circle
from generation.render.video import render_video

STATIC_NAME = "studyapp/device-check.mp4"
CLIP_PATH = Path(__file__).resolve().parents[1] / "static" / STATIC_NAME
SECONDS, FPS, SIZE = 2.0, 30.0, (480, 360)


def device_clip_url() -> str:
    """Where the participant's browser fetches the device check's clip."""
    return static(STATIC_NAME)


def render_device_clip(path: Path = CLIP_PATH) -> Path:
    """Render the synthetic walker as the device check's clip at ``path``."""
    return render_video(walking_in_a_circle(SECONDS, FPS), path, size=SIZE)


if __name__ == "__main__":
    print(render_device_clip())
