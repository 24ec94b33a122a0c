"""Whether a video file holds the whole clip it should, checked before the video is used.

A video cut short (a copy that stopped, a full disk) still opens and its first frames
still decode: MP4 keeps its index (the moov atom) at the front, so the container goes on
declaring the whole length. Only decoding every frame tells. ``read_stream`` decodes the
file's first video stream to the end with ffmpeg and refuses it if any frame fails to
decode or the frames fall short of the length the container declares;
``check_video`` also holds it to the clip it should be (frame count and duration), and
``check_rendered_video`` to what ``render_video`` writes for a motion.
"""

from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg

from generation.motion.types import Motion
from generation.render.draw import frame_indices

DECODE_TIMEOUT_S = 600.0  # an hour of 640x480 video decodes in about a minute on one core
# ffmpeg's log with "level" tags each line with its severity; these mean a frame was lost.
_FAILURE = re.compile(r"\[(error|fatal|panic)\] (.*)")
_DECLARED = re.compile(r"Duration: (\d+):(\d\d):(\d\d(?:\.\d+)?)")


class VideoError(ValueError):
    """A video that is not the whole clip it should be; the message names the file."""

    def __init__(self, path: str | os.PathLike, message: str):
        super().__init__(f"{path}: {message}")
        self.path = str(path)


@dataclass(frozen=True)
class VideoStream:
    """What decoding a video's first stream to its end found."""

    frames: int  # frames that decoded
    seconds: float  # from the first decoded frame's start to the last one's end
    declared_seconds: float | None  # the container's own length, where it states one
    size: tuple[int, int]  # width, height


def read_stream(path: str | os.PathLike, timeout: float = DECODE_TIMEOUT_S) -> VideoStream:
    """Decode every frame of the first video stream of ``path``; VideoError naming the
    file if it cannot be opened, a frame does not decode, or the frames end before the
    length the container declares (by more than a frame)."""
    path = Path(path)
    if not path.is_file():
        raise VideoError(path, "no such file" if not path.exists() else "is not a file")
    # One checksum line per decoded frame on stdout; "file:" keeps a name like "http:x" a file.
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", "-nostats", "-loglevel", "level+info",
               "-i", f"file:{path}", "-map", "0:v:0", "-f", "framecrc", "-"]
    try:
        done = subprocess.run(command, capture_output=True, text=True, errors="replace", timeout=timeout)
    except subprocess.TimeoutExpired:
        raise VideoError(path, f"did not decode within {timeout:g} s") from None
    failures = [m.group(2).strip() for m in map(_FAILURE.search, done.stderr.splitlines()) if m]
    if done.returncode != 0:
        raise VideoError(path, f"does not decode as a video ({failures[-1] if failures else f'ffmpeg exit {done.returncode}'})")
    stream = _decoded(path, done.stdout, done.stderr)
    one_frame = stream.seconds / stream.frames
    if stream.declared_seconds is not None and stream.seconds < stream.declared_seconds - one_frame:
        raise VideoError(path, f"cut short: the file declares {stream.declared_seconds:g} s but its frames end at "
                               f"{stream.seconds:g} s ({stream.frames} frames)")
    if failures:
        raise VideoError(path, f"frames do not decode ({failures[0]}); the file is damaged")
    return stream


def check_video(path: str | os.PathLike, frames: int, fps: float, timeout: float = DECODE_TIMEOUT_S) -> VideoStream:
    """``read_stream``, and the stream is the clip of ``frames`` frames at ``fps``: as
    many frames, lasting as long (within half a frame). VideoError naming the file if not."""
    stream = read_stream(path, timeout)
    clip = f"the clip has {frames} frames ({frames / fps:g} s at {fps:g} fps)"
    if stream.frames != frames:
        raise VideoError(path, f"holds {stream.frames} frames ({stream.seconds:g} s), but {clip}")
    if abs(stream.seconds - frames / fps) > 0.5 / fps:
        raise VideoError(path, f"lasts {stream.seconds:g} s, but {clip}")
    return stream


def check_rendered_video(path: str | os.PathLike, motion: Motion, fps: float | None = None,
                         timeout: float = DECODE_TIMEOUT_S) -> VideoStream:
    """``check_video`` against what ``render_video(motion, path, fps=fps)`` writes."""
    rate = float(fps) if fps is not None else float(motion.fps)
    return check_video(path, len(frame_indices(motion.n_frames, motion.fps, rate)), rate, timeout)


def _decoded(path: Path, checksums: str, log: str) -> VideoStream:
    """The stream from ffmpeg's framecrc lines ("stream, dts, pts, duration, size, hash"
    after "#tb 0: 1/20" and "#dimensions 0: 640x480") and its log's declared duration."""
    header = dict(line[1:].split(": ", 1) for line in checksums.splitlines() if line.startswith("#") and ": " in line)
    rows = [[field.strip() for field in line.split(",")] for line in checksums.splitlines()
            if line.strip() and not line.startswith("#")]
    if not rows:
        raise VideoError(path, "holds no video frames")
    base = Fraction(header.get("tb 0", "1/1"))
    start, end = int(rows[0][2]), int(rows[-1][2]) + int(rows[-1][3])
    width, _, height = header.get("dimensions 0", "0x0").partition("x")
    declared = _DECLARED.search(log)
    declared_seconds = (None if declared is None else
                        int(declared[1]) * 3600 + int(declared[2]) * 60 + float(declared[3]))
    return VideoStream(len(rows), float((end - start) * base), declared_seconds, (int(width), int(height)))
