"""A stimulus video is checked whole before it is used: a real clip rendered by the study's
renderer passes, and the same file cut in half, damaged in the middle, or of another
length than its clip is refused naming the file, although its first frame still decodes.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import imageio_ffmpeg
import pytest

from generation.motion.bvh import load_motion
from generation.motion.types import Motion
from generation.render import render_video
from generation.render.video_check import VideoError, check_rendered_video, check_video, read_stream

SIZE = (160, 120)


@pytest.fixture(scope="module")
def walk(clip_path) -> Motion:
    """Two seconds of a real walk (30 fps in the file)."""
    motion = load_motion(clip_path("walk_normal_001"))
    return Motion(motion.positions[:60], motion.fps, motion.skeleton)


@pytest.fixture(scope="module")
def rendered(walk, tmp_path_factory) -> Path:
    return render_video(walk, tmp_path_factory.mktemp("stimuli") / "walk.mp4", size=SIZE, fps=20)


def first_frame_decodes(path: Path) -> bool:
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path), "-frames:v", "1", "-f", "null", "-"]
    return subprocess.run(command, capture_output=True).returncode == 0


def test_a_rendered_clip_is_its_whole_clip(walk, rendered):
    stream = check_rendered_video(rendered, walk, fps=20)
    assert (stream.frames, stream.seconds, stream.declared_seconds, stream.size) == (40, 2.0, 2.0, SIZE)
    assert check_video(rendered, 40, 20.0) == stream


def test_a_stimulus_cut_in_half_is_refused_naming_the_file(walk, rendered, tmp_path):
    half = tmp_path / "half.mp4"
    data = rendered.read_bytes()
    half.write_bytes(data[: len(data) // 2])
    assert first_frame_decodes(half)  # what a first-frame check accepted
    with pytest.raises(VideoError, match=rf"^{half}: cut short: the file declares 2 s but its frames end at"):
        check_rendered_video(half, walk, fps=20)
    with pytest.raises(VideoError, match=f"^{half}: cut short"):
        read_stream(half)


def test_a_stimulus_damaged_in_the_middle_is_refused(rendered, tmp_path):
    damaged = tmp_path / "damaged.mp4"
    data = bytearray(rendered.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 200] = bytes(b ^ 0x5A for b in data[middle : middle + 200])
    damaged.write_bytes(bytes(data))
    with pytest.raises(VideoError, match=f"^{damaged}: frames do not decode"):
        read_stream(damaged)


def test_a_whole_video_of_another_clip_is_refused(walk, rendered, tmp_path):
    with pytest.raises(VideoError, match=r"holds 40 frames \(2 s\), but the clip has 60 frames \(2 s at 30 fps\)"):
        check_rendered_video(rendered, walk)  # the clip at its own 30 fps
    with pytest.raises(VideoError, match=r"lasts 2 s, but the clip has 40 frames \(4 s at 10 fps\)"):
        check_video(rendered, 40, 10.0)


@pytest.mark.parametrize("content", [None, b"", b"\x00\x00\x00\x18ftypisom" + b"\x00" * 200, b"not a video at all"],
                         ids=["missing", "empty", "an ftyp box and nothing else", "text"])
def test_what_is_no_video_is_refused_naming_the_file(content, tmp_path):
    path = tmp_path / "clip.mp4"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(VideoError, match=f"^{path}: "):
        read_stream(path)


def test_a_file_named_like_a_protocol_is_read_as_a_file(rendered, tmp_path, monkeypatch):
    odd = tmp_path / "http:"
    odd.mkdir()
    shutil.copy(rendered, odd / "walk.mp4")
    monkeypatch.chdir(tmp_path)
    assert read_stream(Path("http:") / "walk.mp4").frames == 40
