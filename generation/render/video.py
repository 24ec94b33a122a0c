"""MP4 stimuli: frames streamed straight into ffmpeg's H.264 encoder.

Output plays progressively in Chromium, Firefox and Safari: H.264 (libx264) in yuv420p
(the only chroma layout all three decode), even frame sizes (yuv420p needs them), and the
moov atom moved before the media data (``+faststart``) so playback starts before the whole
file has arrived. Colours are converted and tagged as BT.709 so browsers agree on them.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg
import numpy as np

from generation.motion.types import Motion
from generation.render.camera import Camera
from generation.render.draw import FrameDrawer
from generation.files import atomic_output
from generation.render.style import Style


def render_video(
    motion: Motion,
    path: str | os.PathLike,
    camera: Camera = Camera(),
    size: tuple[int, int] = (640, 480),
    fps: float | None = None,
    root_path: np.ndarray | None = None,
    style: Style = Style(),
    crf: int = 20,
    preset: str = "veryfast",
    x264_params: str = "me=dia:subme=1",
    control_path: np.ndarray | None = None,
) -> Path:
    """Render ``motion`` as a stick-figure MP4 at ``path`` and return the path.

    ``fps`` None keeps the motion's rate; another rate picks the nearest frame in time.
    ``root_path`` (T, 2) x, z or (T, 3) overrides the floor path drawn under the figure.
    ``control_path`` (T, 2) draws the path a control asks for, the camera following it
    (``FrameDrawer``): the same for every system's clip of that control.
    ``crf``, ``preset`` and ``x264_params`` are libx264's quality and speed settings. The
    default params pick the cheapest motion search: a following camera slides the whole
    floor every frame, and on 2 cores this measured ~1.5x faster encoding than plain
    ``veryfast`` for ~10% larger files. Pass ``x264_params=""`` to use the preset's own.
    """
    width, height = size
    if width % 2 or height % 2:
        raise ValueError(f"H.264 in yuv420p needs even frame dimensions, got {width}x{height}")
    drawer = FrameDrawer(motion, camera, size, fps, root_path, style, control_path)
    path = Path(path)
    with atomic_output(path) as tmp:
        _encode(drawer, tmp, path, crf, preset, x264_params)
    return path


def _encode(drawer: FrameDrawer, out: Path, target: Path, crf: int, preset: str, x264_params: str) -> None:
    """Stream the frames into ffmpeg writing ``out`` (the temporary file for ``target``)."""
    width, height = drawer.size
    rate = Fraction(drawer.fps).limit_denominator(100_000)
    command = [
        imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostats", "-loglevel", "error",
        "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(rate),
        "-i", "pipe:0", "-an",
        "-vf", "scale=out_color_matrix=bt709:out_range=tv,format=yuv420p",
        "-c:v", "libx264", "-preset", preset, "-crf", str(crf),
        *(["-x264-params", x264_params] if x264_params else []),
        "-colorspace", "bt709", "-color_primaries", "bt709", "-color_trc", "bt709",
        "-color_range", "tv", "-movflags", "+faststart", "-f", "mp4", "-y", str(out),
    ]  # fmt: skip
    # stderr goes to a file, not a pipe: an unread pipe that fills up would block ffmpeg.
    with tempfile.TemporaryFile() as log:
        process = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=log)
        try:
            for k in range(len(drawer)):
                process.stdin.write(drawer.image(k).tobytes())
        except BrokenPipeError:
            pass  # ffmpeg exited early; its exit status and log below say why
        except BaseException:
            process.kill()
            raise
        finally:
            with contextlib.suppress(BrokenPipeError):
                process.stdin.close()
            process.wait()
        if process.returncode != 0:
            log.seek(0)
            message = log.read().decode(errors="replace").strip()
            raise RuntimeError(f"ffmpeg failed (exit {process.returncode}) rendering {target}: {message}")
