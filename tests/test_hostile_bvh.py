"""Hostile BVH files and their side files: each gets an error naming the file and the line
(or field), never an OverflowError, a RecursionError or gigabytes of frames.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from generation.cli import main as cli_main
from generation.motion import BVHError, read_bvh, write_bvh
from generation.motion.bvh import bvh_duration, read_bvh_skeleton
from generation.motion.clip_files import read_labels
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.types import Motion
from generation.render.draw import FrameDrawer
from tests.test_motion_bvh import SMALL_BVH

HEADER = SMALL_BVH.split("MOTION")[0]
ROW = "1 90 2 10 20 30 5 6 7 40 50 60"


def motion_section(frames: str = "2", frame_time: str = "0.0333333", rows: tuple[str, ...] = (ROW, ROW)) -> str:
    return HEADER + f"MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n" + "".join(r + "\n" for r in rows)


FRAME_TIME_LINE = HEADER.count("\n") + 3

HOSTILE_BVH = {
    "Frame Time 1e-320": (motion_section(frame_time="1e-320"), FRAME_TIME_LINE, "Frame Time 1e-320 s is outside"),
    "Frame Time 1e6": (motion_section(frame_time="1e6"), FRAME_TIME_LINE, "Frame Time 1e6 s is outside"),
    "Frame Time 1e300": (motion_section(frame_time="1e300"), FRAME_TIME_LINE, "Frame Time 1e300 s is outside"),
    "Frame Time 0": (motion_section(frame_time="0"), FRAME_TIME_LINE, "Frame Time must be positive"),
    "Frame Time nan": (motion_section(frame_time="nan"), FRAME_TIME_LINE, "Frame Time must be positive"),
    "Frame Time inf": (motion_section(frame_time="inf"), FRAME_TIME_LINE, "Frame Time must be positive"),
    "Frames 0": (motion_section(frames="0", rows=()), FRAME_TIME_LINE - 1, "declares 0 frames"),
    "Frames with 5,000 digits": (motion_section(frames="9" * 5000), None, "is not a number"),
    "a value of 1e308": (motion_section(rows=(ROW, ROW.replace("90", "1e308"))), FRAME_TIME_LINE + 2,
                         "the frame row has a value beyond ±1e+09"),
    "a value of 1e400": (motion_section(rows=(ROW.replace("90", "1e400"), ROW)), FRAME_TIME_LINE + 1,
                         "NaN or infinite"),
    "an OFFSET of 1e308": (SMALL_BVH.replace("OFFSET 0 10 0", "OFFSET 0 1e308 0"), 8, "OFFSET has a value beyond"),
    "every CHANNELS 0": ("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 0\n}\nMOTION\nFrames: 2\nFrame Time: 0.05\n\n\n",
                         7, "no joint has channels"),
    "a row too short": (motion_section(rows=(ROW, "1 2 3")), FRAME_TIME_LINE + 2, "needs 12 numbers, found 3"),
    "not text": (b"HIERARCHY\n\xff\xfe\x00ROOT", None, "not a text file"),
}


@pytest.mark.parametrize("text, line, message", HOSTILE_BVH.values(), ids=HOSTILE_BVH.keys())
def test_a_hostile_bvh_is_refused_naming_the_file_and_line(text, line, message, tmp_path):
    path = tmp_path / "clip.bvh"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(BVHError) as caught:
        read_bvh(path)
    assert message in str(caught.value)
    assert str(caught.value).startswith(f"{path}:{line}: " if line else f"{path}")


@pytest.mark.parametrize("text, line, message", HOSTILE_BVH.values(), ids=HOSTILE_BVH.keys())
def test_bvh_duration_refuses_a_header_that_read_bvh_refuses(text, line, message, tmp_path):
    path = tmp_path / "clip.bvh"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    if line is not None and line > FRAME_TIME_LINE:
        assert bvh_duration(path) == pytest.approx(2 * 0.0333333)  # the rows are not read
        return
    with pytest.raises(BVHError) as caught:
        bvh_duration(path)
    assert message in str(caught.value)
    assert str(caught.value).startswith(f"{path}:{line}: " if line else f"{path}")


@pytest.mark.parametrize("content", [bytes(range(256)) * 4, b"\x00" * 100, b"MOTION\nFrames: 2\nFrame Time: 0.05\n"],
                         ids=["binary garbage", "NUL bytes", "no hierarchy"])
def test_bvh_duration_refuses_what_is_no_bvh_file(content, tmp_path):
    path = tmp_path / "clip.bvh"
    path.write_bytes(content)
    with pytest.raises(BVHError, match=f"^{path}"):
        bvh_duration(path)


def test_bvh_duration_reads_the_header_of_a_real_clip(clip_path):
    path = clip_path("walk_normal_001")
    assert bvh_duration(path) == pytest.approx(read_bvh(path).to_motion().duration)


@pytest.mark.parametrize("reader", [read_bvh, bvh_duration, read_bvh_skeleton])
def test_a_missing_bvh_file_is_a_bvh_error_naming_it(reader, tmp_path):
    with pytest.raises(BVHError, match=f"^{tmp_path / 'gone.bvh'}: no such file$"):
        reader(tmp_path / "gone.bvh")


HOSTILE_SIDE_FILES = {
    "a list": ("[0, 1]", "expected a JSON object with 'content' and 'style', got a list"),
    "a string": ('"walk"', "got a str"),
    "a fractional label": ('{"content": 1.5}', "'content' must be a label index or name, got 1.5"),
    "a nested label": ('{"style": {"x": 1}}', "'style' must be a label index or name"),
    "broken JSON": ('{"content": ', "invalid JSON"),
    "not UTF-8": (b'{"content": "\xe9"}', "not UTF-8 text"),
}


@pytest.mark.parametrize("content, message", HOSTILE_SIDE_FILES.values(), ids=HOSTILE_SIDE_FILES.keys())
def test_a_hostile_side_file_is_refused_naming_it(content, message, tmp_path):
    bvh = tmp_path / "clip.bvh"
    bvh.write_text(SMALL_BVH)
    side = tmp_path / "clip.json"
    side.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(ValueError) as caught:
        read_labels(bvh)
    assert str(caught.value).startswith(str(side)) and message in str(caught.value)


def test_a_5000_joint_chain_is_written_and_read_back_without_recursion(tmp_path):
    n = 5000
    lines = ["HIERARCHY"]
    for j in range(n):
        channels = "6 Xposition Yposition Zposition" if j == 0 else "3"
        lines += [f"{'ROOT' if j == 0 else 'JOINT'} j{j}", "{", "OFFSET 0 1 0", f"CHANNELS {channels} Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}", *["}"] * n, "MOTION", "Frames: 2", "Frame Time: 0.05"]
    lines += [" ".join(["0"] * (3 * n + 3)), " ".join(["1"] * (3 * n + 3))]
    source = tmp_path / "chain.bvh"
    source.write_text("\n".join(lines) + "\n")

    bvh = read_bvh(source)
    again = read_bvh(write_bvh(bvh, tmp_path / "again.bvh"))

    assert again.skeleton.names == bvh.skeleton.names and len(bvh.skeleton.names) == n
    assert np.array_equal(again.skeleton.parents, np.arange(-1, n - 1))
    assert np.array_equal(again.values, bvh.values)
    assert bvh.to_motion().positions[0, -1, 1] == pytest.approx(n - 1)


def test_the_renderer_refuses_a_motion_of_days_before_planning_its_frames(tmp_path):
    (tmp_path / "clip.bvh").write_text(SMALL_BVH)
    skeleton = read_bvh(tmp_path / "clip.bvh").skeleton
    slow = Motion(np.zeros((2, skeleton.n_joints, 3)), fps=1e-6, skeleton=skeleton)  # two frames, 11 days
    with pytest.raises(ValueError, match=r"the motion lasts 2e\+06 s \(2 frames at 1e-06 fps\); videos are at most"):
        FrameDrawer(slow, fps=20.0)
    with pytest.raises(ValueError, match="fps must be positive and finite"):
        Motion(np.zeros((2, skeleton.n_joints, 3)), fps=float("inf"), skeleton=skeleton)


def test_a_clip_failing_deep_in_the_motion_code_names_its_file(tmp_path):
    folder = tmp_path / "clips"
    folder.mkdir()
    # A rig with no joint that looks like hips or legs: the failure comes from the
    # body-finding code, which knows nothing of files.
    (folder / "odd.bvh").write_text(SMALL_BVH.replace("pelvis", "base").replace("leg", "arm"))
    with pytest.raises(ValueError) as caught:
        build_dataset(folder, cache_dir=tmp_path / "cache", progress=False)
    assert str(caught.value).startswith(str(folder / "odd.bvh"))
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


HOSTILE_DATASET_OPTIONS = {
    "fps inf": ({"fps": float("inf")}, "dataset option fps must be a number of frames per second above 0"),
    "fps 0": ({"fps": 0.0}, "dataset option fps must be"),
    "fps nan": ({"fps": float("nan")}, "dataset option fps must be"),
    "window 0": ({"window_seconds": 0.0}, "dataset option window_seconds must be long enough for two frames"),
    "window of one frame": ({"window_seconds": 0.05}, "window_seconds must be long enough for two frames at 20 fps"),
    "holdout -1": ({"holdout_fraction": -1.0}, "dataset option holdout_fraction must be at least 0 and below 1"),
    "holdout 1": ({"holdout_fraction": 1.0}, "holdout_fraction must be at least 0 and below 1"),
    "validation 2": ({"validation_fraction": 2.0}, "validation_fraction must be at least 0 and below 1"),
    "overlap 1": ({"overlap": 1.0}, "dataset option overlap must be at least 0 and below 1"),
    "scale nan": ({"scale": float("nan")}, "dataset option scale must be a positive number"),
    "scale 0": ({"scale": 0.0}, "dataset option scale must be a positive number"),
}


@pytest.mark.parametrize("options, message", HOSTILE_DATASET_OPTIONS.values(), ids=HOSTILE_DATASET_OPTIONS.keys())
def test_hostile_dataset_options_are_refused_before_anything_is_read(options, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        DatasetOptions(**options)


def test_a_cache_folder_that_is_a_file_is_refused_by_name(tmp_path):
    (tmp_path / "clips").mkdir()
    (tmp_path / "clips" / "clip.bvh").write_text(SMALL_BVH)
    (tmp_path / "cache").write_text("not a folder")
    with pytest.raises(ValueError, match=f"the cache folder {tmp_path / 'cache'} is a file"):
        build_dataset(tmp_path / "clips", cache_dir=tmp_path / "cache", progress=False)
    assert (tmp_path / "cache").read_text() == "not a folder"


@pytest.fixture
def clips(tmp_path) -> Path:
    folder = tmp_path / "clips"
    folder.mkdir()
    (folder / "clip.bvh").write_text(SMALL_BVH)
    return folder


HOSTILE_COMMANDS = {
    "info on a folder": (["info", "{clips}"], "{clips}: is a folder, not a BVH file"),
    "build-dataset --fps inf": (["build-dataset", "{clips}", "--fps", "inf"], "dataset option fps must be"),
    "build-dataset --window 0": (["build-dataset", "{clips}", "--window", "0"], "dataset option window_seconds"),
    "build-dataset --holdout -1": (["build-dataset", "{clips}", "--holdout", "-1"], "holdout_fraction must be at least 0"),
    "build-dataset --scale nan": (["build-dataset", "{clips}", "--scale", "nan"], "scale must be a positive number"),
    "build-dataset --cache-dir a file": (["build-dataset", "{clips}", "--cache-dir", "{clips}/clip.bvh"],
                                         "the cache folder {clips}/clip.bvh is a file"),
    "render a folder": (["render", "{clips}", "--out", "{clips}/out.mp4"], "{clips}: is a folder, not a BVH file"),
}


@pytest.mark.parametrize("command, message", HOSTILE_COMMANDS.values(), ids=HOSTILE_COMMANDS.keys())
def test_hostile_motion_commands_exit_2_naming_the_problem_and_leave_nothing(command, message, clips, tmp_path,
                                                                              capsys, monkeypatch):
    monkeypatch.setenv("MOTION_CACHE_DIR", str(tmp_path / "cache"))
    try:
        status = cli_main([word.format(clips=clips) for word in command])
    except SystemExit as exit:  # argparse refuses an argument itself, with the same status
        status = exit.code
    assert status == 2
    err = capsys.readouterr().err
    assert message.format(clips=clips) in err and "Traceback" not in err
    assert sorted(p.name for p in clips.iterdir()) == ["clip.bvh"]
    assert not (tmp_path / "cache").exists() or not list((tmp_path / "cache").iterdir())


def test_a_folder_of_one_frame_clips_is_refused_for_having_no_training_windows(motion_data, tmp_path, capsys):
    folder = tmp_path / "one-frame"
    folder.mkdir()
    for source in sorted((motion_data / "data").glob("*_walk_*.bvh"))[:4]:
        lines = source.read_text().splitlines()
        motion = lines.index("MOTION")
        (folder / source.name).write_text("\n".join([*lines[: motion + 1], "Frames: 1", *lines[motion + 2 : motion + 4]]) + "\n")
    assert cli_main(["build-dataset", str(folder), "--cache-dir", str(tmp_path / "cache")]) == 2
    assert "no training windows" in capsys.readouterr().err
    assert not list((tmp_path / "cache").glob("dataset-*.npz"))


@pytest.fixture
def labelled(tmp_path) -> Path:
    """A clip in a folder whose cfg/ lists the contents walk and run (with a dataset prefix)."""
    folder = tmp_path / "labelled"
    (folder / "cfg").mkdir(parents=True)
    (folder / "cfg" / "content_label.txt").write_text("dataset-9_walk\ndataset-9_run\n")
    (folder / "clip.bvh").write_text(SMALL_BVH)
    return folder


@pytest.mark.parametrize("entry, message", [
    ('{"content": "abc"}', "'content' is 'abc', which is not a label of {names} (walk, run)"),
    ('{"content": 2}', "'content' is 2, but {names} lists 2 labels (0 to 1)"),
    ('{"content": -1}', "'content' is -1, but {names} lists 2 labels (0 to 1)"),
], ids=["a name not in the list", "an index past the list", "a negative index"])
def test_a_label_that_the_label_list_lacks_is_refused_naming_the_file_and_field(entry, message, labelled):
    (labelled / "clip.json").write_text(entry)
    with pytest.raises(ValueError) as caught:
        read_labels(labelled / "clip.bvh")
    names = labelled / "cfg" / "content_label.txt"
    assert str(caught.value) == f"{labelled / 'clip.json'}: {message.format(names=names)}"


@pytest.mark.parametrize("entry", ['{"content": "run"}', '{"content": "dataset-9_run"}', '{"content": 1}'])
def test_a_label_of_the_list_is_read_by_name_or_index(entry, labelled):
    (labelled / "clip.json").write_text(entry)
    assert read_labels(labelled / "clip.bvh")[0] in ("run", "dataset-9_run")
