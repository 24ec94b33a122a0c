"""The stick-figure renderer: browser-ready MP4s, figures where the camera says, atomic writes.

Everything runs on the synthetic walker (no data files) at small sizes, so the whole file
takes a few seconds.
"""

from __future__ import annotations

import json
import re
import struct
import subprocess
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from generation.motion.types import Motion, Skeleton
from generation.render import Camera, FrameDrawer, Style, contact_sheet, render_video
from generation.render.draw import frame_indices
from generation.render.figure import LEFT, RIGHT, CENTRE, body_root_index, figure_bones, joint_sides
from generation.render.synthetic import walking_in_a_circle

SIZE = (160, 120)


def decode(path: Path, size: tuple[int, int] = SIZE) -> np.ndarray:
    """All frames as (T, h, w, 3) uint8, decoded by imageio's ffmpeg binary.

    (imageio_ffmpeg.read_frames would do, but it leaves its pipes for the garbage collector.)
    """
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    command = [ffmpeg, "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24", "-"]
    raw = subprocess.run(command, capture_output=True, check=True).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, size[1], size[0], 3)


def top_level_boxes(path: Path) -> list[str]:
    """The types of an MP4 file's top-level boxes, in file order."""
    data, boxes, at = path.read_bytes(), [], 0
    while at + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[at : at + 8])
        if size == 1:  # 64-bit size follows the type
            size = struct.unpack(">Q", data[at + 8 : at + 16])[0]
        boxes.append(kind.decode("latin-1"))
        at += size if size else len(data)
    return boxes


def dark_pixels(frame: np.ndarray, threshold: int = 120) -> np.ndarray:
    """(row, col) of pixels much darker than the light background: the figure's bones."""
    return np.argwhere(frame.mean(axis=-1) < threshold)


@pytest.fixture(scope="module")
def walker() -> Motion:
    return walking_in_a_circle(seconds=1.0, fps=30.0)


@pytest.fixture(scope="module")
def video(walker, tmp_path_factory) -> Path:
    return render_video(walker, tmp_path_factory.mktemp("video") / "walker.mp4", size=SIZE, fps=20)


def test_video_is_h264_yuv420p_with_moov_before_mdat(video):
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    probe = subprocess.run([ffmpeg, "-hide_banner", "-i", str(video)], capture_output=True, text=True)
    stream = next(line for line in probe.stderr.splitlines() if "Video:" in line)
    assert "Video: h264" in stream
    assert re.search(r"\byuv420p\b", stream)
    assert f"{SIZE[0]}x{SIZE[1]}" in stream
    boxes = top_level_boxes(video)
    assert "moov" in boxes and "mdat" in boxes
    assert boxes.index("moov") < boxes.index("mdat"), f"moov must precede mdat for progressive play: {boxes}"


def test_video_has_one_frame_per_output_time_at_the_requested_size(walker, video, tmp_path):
    frames = decode(video)
    assert frames.shape == (20, SIZE[1], SIZE[0], 3)  # 1 s resampled from 30 to 20 fps
    native = decode(render_video(walker, tmp_path / "native.mp4", size=SIZE))
    assert len(native) == walker.n_frames


def test_resampling_picks_the_nearest_frame_in_time():
    assert frame_indices(6, 30.0, 20.0).tolist() == [0, 2, 3, 5]  # t = 0, 0.05, 0.1, 0.15 s
    assert frame_indices(3, 30.0, 60.0).tolist() == [0, 1, 1, 2, 2, 2]
    assert frame_indices(1, 30.0, 5.0).tolist() == [0]


def test_odd_frame_sizes_are_refused(walker, tmp_path):
    with pytest.raises(ValueError, match="even"):
        render_video(walker, tmp_path / "odd.mp4", size=(161, 120))


def test_joints_appear_where_the_camera_projects_them(walker, video):
    frames = decode(video)
    drawer = FrameDrawer(walker, size=SIZE, fps=20)
    background = np.array(Style().background)
    for k in (0, 10, 19):
        source = drawer.source[k]
        pixels, visible = drawer.camera.project(walker.positions[source], drawer.targets[k], SIZE)
        assert visible.all()
        for j in (walker.skeleton.index("Head"), walker.skeleton.index("Foot_L")):
            x, y = np.round(pixels[j]).astype(int)
            patch = frames[k, y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 3).astype(int)
            difference = np.abs(patch - background).sum(axis=1).max()
            assert difference > 100, f"no joint drawn at {x, y} in frame {k}"


def test_a_figure_further_right_is_drawn_further_right():
    # The walker stands still for half a second, then steps sideways along the camera's
    # right axis; with a fixed camera its dark pixels must move right on screen.
    camera = Camera(follow=False)
    still = walking_in_a_circle(seconds=0.1, fps=10.0).positions[:1]
    shift = np.concatenate([np.zeros(5), np.full(5, 80.0)])[:, None, None] * camera.rotation[0]
    motion = Motion(still + shift, fps=10.0, skeleton=walking_in_a_circle(0.1, 10.0).skeleton)
    drawer = FrameDrawer(motion, camera, SIZE)
    before, after = dark_pixels(drawer.frame(0)), dark_pixels(drawer.frame(9))
    assert len(before) > 20 and len(after) > 20
    assert after[:, 1].mean() > before[:, 1].mean() + 10
    assert abs(after[:, 0].mean() - before[:, 0].mean()) < 5


def test_follow_camera_keeps_the_walker_near_the_centre(walker):
    drawer = FrameDrawer(walking_in_a_circle(seconds=3.0, fps=30.0), Camera(), SIZE)
    columns = [dark_pixels(drawer.frame(k))[:, 1].mean() for k in range(0, len(drawer), 15)]
    assert np.all(np.abs(np.array(columns) - SIZE[0] / 2) < SIZE[0] / 6)


def test_same_input_gives_identical_frames(walker, video, tmp_path):
    again = render_video(walker, tmp_path / "again.mp4", size=SIZE, fps=20)
    assert decode(again).tobytes() == decode(video).tobytes()


def test_camera_and_style_round_trip_through_json():
    camera = Camera(azimuth=-20.0, elevation=30.0, distance=600.0, fov=35.0, follow=False)
    assert Camera.from_dict(json.loads(json.dumps(camera.to_dict()))) == camera
    style = Style(bone=(1, 2, 3), supersample=3)
    assert Style.from_dict(json.loads(json.dumps(style.to_dict()))) == style
    with pytest.raises(ValueError, match="unknown Camera fields: zoom"):
        Camera.from_dict({"zoom": 2})


def test_segments_crossing_the_near_plane_are_cut_there():
    camera = Camera(near=10.0)
    a = np.array([[0.0, 0.0, -50.0], [0.0, 0.0, -5.0], [1.0, 2.0, 20.0]])
    b = np.array([[0.0, 0.0, 50.0], [0.0, 0.0, -1.0], [3.0, 4.0, 40.0]])
    ca, cb, keep = camera.clip_segments(a, b)
    assert keep.tolist() == [True, False, True]
    np.testing.assert_allclose(ca[0], [0.0, 0.0, 10.0])
    np.testing.assert_allclose(cb[0], b[0])
    np.testing.assert_allclose([ca[2], cb[2]], [a[2], b[2]])


def test_a_camera_inside_the_scene_still_renders(walker):
    # Low and close: parts of the floor path and grid are behind the camera.
    drawer = FrameDrawer(walker, Camera(distance=60.0, elevation=5.0, target_height=20.0), SIZE)
    frame = drawer.frame(0)
    assert frame.shape == (SIZE[1], SIZE[0], 3) and np.isfinite(frame).all()


def test_failure_mid_render_leaves_no_file(walker, tmp_path, monkeypatch):
    path = tmp_path / "broken.mp4"
    path.write_bytes(b"previous version")
    original = FrameDrawer.image

    def fail_at_frame_5(self, k):
        if k == 5:
            raise RuntimeError("drawing failed")
        return original(self, k)

    monkeypatch.setattr(FrameDrawer, "image", fail_at_frame_5)
    with pytest.raises(RuntimeError, match="drawing failed"):
        render_video(walker, path, size=SIZE)
    assert path.read_bytes() == b"previous version"  # the old file is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken.mp4"]  # no temporary left


def test_ffmpeg_failure_is_reported_and_leaves_no_file(walker, tmp_path):
    with pytest.raises(RuntimeError, match="ffmpeg failed"):
        render_video(walker, tmp_path / "clip.mp4", size=SIZE, preset="no-such-preset")
    assert list(tmp_path.iterdir()) == []


def test_missing_folders_are_created(walker, tmp_path):
    path = render_video(walker, tmp_path / "new" / "clip.mp4", size=SIZE)
    assert path.is_file() and oct(path.stat().st_mode & 0o777) != oct(0o600)


def test_contact_sheet_is_n_frames_wide(walker, tmp_path):
    from PIL import Image

    path = contact_sheet(walker, tmp_path / "sheet.png", n=4, size=(100, 80))
    with Image.open(path) as sheet:
        assert sheet.format == "PNG" and sheet.size == (400, 80)
        # Every panel shows the figure.
        pixels = np.asarray(sheet.convert("RGB"))
        for i in range(4):
            assert len(dark_pixels(pixels[:, i * 100 : (i + 1) * 100])) > 10
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sheet.png"]


def test_root_path_override_is_drawn_on_the_floor(walker):
    style = Style(draw_shadow=False)
    camera = Camera(follow=False, elevation=60.0)
    path = np.zeros((walker.n_frames, 2))
    path[:, 0] = np.linspace(-300, 300, walker.n_frames)  # a straight line along x
    with_path = FrameDrawer(walker, camera, SIZE, root_path=path, style=style).frame(0)
    with pytest.raises(ValueError, match="root_path must have shape"):
        FrameDrawer(walker, camera, SIZE, root_path=path[:-1])
    future = np.array(style.path_future)
    near_future = np.abs(with_path.astype(int) - future).sum(axis=-1) < 30
    assert near_future.sum() > 20


def test_reference_joints_above_the_pelvis_are_not_drawn_and_sides_follow_the_mirror_pairs():
    skeleton = Skeleton(
        names=("joint_Root", "Hips", "Spine", "UpperLeg_L", "UpperLeg_R", "mixamorig:LeftFoot", "mixamorig:RightFoot"),
        parents=np.array([-1, 0, 1, 1, 1, 3, 4]),
        offsets=np.zeros((7, 3)),
    )
    assert body_root_index(skeleton) == 1
    assert figure_bones(skeleton) == [(1, 2), (1, 3), (1, 4), (3, 5), (4, 6)]
    assert joint_sides(skeleton) == [CENTRE, CENTRE, CENTRE, LEFT, RIGHT, LEFT, RIGHT]


def test_the_figure_fills_the_same_share_of_the_frame_whatever_its_size(walker):
    def height(motion, camera=Camera()):
        drawer = FrameDrawer(motion, camera, SIZE)
        pixels = drawer.camera.to_pixels(drawer.joints_cam[0], SIZE)
        return np.ptp(pixels[:, 1])

    giant = Motion(walker.positions * 2.5, walker.fps,
                   Skeleton(walker.skeleton.names, walker.skeleton.parents, walker.skeleton.offsets * 2.5))
    assert height(giant) == pytest.approx(height(walker), rel=1e-6)
    assert 0.3 * SIZE[1] < height(walker) < 0.6 * SIZE[1]
    framed = Camera().framing(200.0)
    assert framed.target_height == pytest.approx(0.58 * 200.0)
    assert framed.distance == pytest.approx(200.0 / (2 * 0.48 * np.tan(np.radians(20.0))))
    # A camera with its own distance (as studies made before framing stored) keeps it.
    fixed = Camera(distance=420.0, target_height=85.0)
    assert height(giant, fixed) > 2 * height(walker, fixed)
    with pytest.raises(ValueError, match="call framing"):
        Camera().eye_offset()


def floor_like(frame: np.ndarray) -> np.ndarray:
    """(h, w) mask of pixels showing bare floor: light and grey (the background, the grid
    and their blends), not a bone, a path or a shadow."""
    return (frame.min(axis=-1) > 195) & (np.ptp(frame.astype(int), axis=-1) < 20)


def straight_control(n_frames: int, fps: float) -> np.ndarray:
    """The floor path (x, z) of a control walking 100 cm/s along +z from the origin."""
    return np.column_stack([np.zeros(n_frames), 100.0 * np.arange(n_frames) / fps])


def test_a_control_path_is_drawn_where_the_camera_projects_it():
    walker = walking_in_a_circle(seconds=2.0, fps=20.0)
    control = straight_control(walker.n_frames, walker.fps)
    style = Style(draw_shadow=False, draw_future_path=False)
    hidden = Style(draw_shadow=False, draw_future_path=False,  # the same frames without the control
                   control_past=style.background, control_future=style.background)
    size = (320, 240)
    drawer, plain = (FrameDrawer(walker, Camera(elevation=35.0), size, style=s, control_path=control)
                     for s in (style, hidden))
    end = control[-1, 1]  # its interior: a line has no caps, so its ends may fall a pixel short
    dense = np.column_stack([np.zeros(400), np.zeros(400), np.linspace(0.01 * end, 0.99 * end, 400)])
    for k in (0, 20, 39):
        frame, without = drawer.frame(k), plain.frame(k)
        drawn = (frame != without).any(axis=-1)
        pixels, visible = drawer.camera.project(dense, drawer.targets[k], size)
        inside = visible & (pixels >= 0).all(axis=1) & (pixels < np.array(size) - 1).all(axis=1)
        points = np.round(pixels[inside]).astype(int)
        floor = floor_like(without)[points[:, 1], points[:, 0]]  # not under the figure or its own path
        assert floor.sum() > 50, f"the control's path is out of view in frame {k}"
        assert drawn[points[:, 1], points[:, 0]][floor].all(), f"frame {k}: the control's path is missing where it projects"
        rows, cols = np.nonzero(drawn)
        distance = np.hypot(cols[:, None] - pixels[inside, 0], rows[:, None] - pixels[inside, 1]).min(axis=1)
        assert distance.max() < 4, f"frame {k}: the control is drawn {distance.max():.1f} px off its path"
        colours = frame[drawn].astype(int)
        assert (np.abs(colours - np.array(style.control_past)).sum(axis=1) < 30).any() or k == 0
        assert (np.abs(colours - np.array(style.control_future)).sum(axis=1) < 30).any()


def along_the_control(motion: Motion) -> Motion:
    """``motion`` moved to start at the origin and turned to set off along +z, as
    ``straight_control``'s path does (the synthetic walker sets off along +x)."""
    start = motion.positions[0, body_root_index(motion.skeleton)] * np.array([1.0, 0.0, 1.0])
    x, y, z = np.moveaxis(motion.positions - start, -1, 0)
    return Motion(np.stack([-z, y, x], axis=-1), motion.fps, motion.skeleton)


def test_two_systems_clips_of_one_control_draw_the_same_control_path_from_the_same_camera():
    control = straight_control(40, 20.0)
    # Two figures that keep near the path, each its own way.
    circling = along_the_control(walking_in_a_circle(seconds=2.0, fps=20.0, radius=600.0))
    tighter = along_the_control(walking_in_a_circle(seconds=2.0, fps=20.0, radius=300.0, speed=70.0))
    style = Style()
    hidden = Style(control_past=style.background, control_future=style.background)  # same camera, no control drawn
    drawers = [FrameDrawer(m, Camera(), SIZE, style=s, control_path=control)
               for m in (circling, tighter) for s in (style, hidden)]
    assert np.array_equal(drawers[0].targets, drawers[2].targets)  # the camera follows the control, not the figure
    compared = 0
    for k in range(0, 40, 6):
        a, a_plain, b, b_plain = (d.frame(k) for d in drawers)
        figures_apart = (a_plain == b_plain).all(axis=-1)  # everything but the two figures and their own paths
        assert figures_apart.mean() > 0.8
        assert np.array_equal(a[figures_apart], b[figures_apart]), f"frame {k}: the control is drawn differently"
        control_pixels = (a != a_plain).any(axis=-1) & figures_apart
        compared += int(control_pixels.sum())
    assert compared > 200  # the comparison covered the control's path, not an empty floor


def test_a_control_path_of_another_length_than_the_motion_is_refused(walker):
    with pytest.raises(ValueError, match=r"control_path must have shape \(30, 2\).*got \(29, 2\)"):
        FrameDrawer(walker, size=SIZE, control_path=np.zeros((29, 2)))


def test_a_figure_that_strays_far_from_the_control_path_stays_in_frame_to_the_end():
    """A mismatched clip: the figure walks a small circle while the page's control goes
    straight on across the view, 5 m apart at the end. The camera follows the path while
    the figure is near it, and the figure once it strays farther than the frame holds."""
    frames = 120
    across = Camera().rotation[0, [0, 2]] / np.linalg.norm(Camera().rotation[0, [0, 2]])  # the camera's right
    control = np.outer(100.0 * np.arange(frames) / 20.0, across)
    stray = walking_in_a_circle(seconds=frames / 20.0, fps=20.0, radius=100.0, speed=80.0)
    assert np.linalg.norm(stray.positions[-1, body_root_index(stray.skeleton), [0, 2]] - control[-1]) > 500
    drawer = FrameDrawer(stray, Camera(), SIZE, control_path=control)
    pixels = drawer.camera.to_pixels(drawer.joints_cam[:, drawer.shown_joints], drawer.size)
    inside = (pixels >= 0).all(axis=-1) & (pixels < np.array(SIZE)).all(axis=-1)
    assert inside.all(), f"joints leave the frame from frame {int(np.argwhere(~inside.all(axis=1))[0, 0])}"
    near = FrameDrawer(along_the_control(walking_in_a_circle(seconds=2.0, fps=20.0, radius=600.0)), Camera(), SIZE,
                       control_path=straight_control(40, 20.0))
    path_only = Camera().framing(150.0).targets(straight_control(40, 20.0), 20.0)
    np.testing.assert_allclose(near.targets[:, [0, 2]], path_only[:, [0, 2]])  # near its path: the path alone
