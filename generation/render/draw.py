"""Drawing one frame: floor grid, control path, root path, shadow and stick figure, as RGB pixels.

``FrameDrawer`` does the per-clip work once (projecting every joint of every output frame
in one vectorised step, sorting bones by depth, drawing the floor grid when the camera
does not move) so that a frame costs a handful of PIL calls. The figure is antialiased by
drawing only its bounding box at ``Style.supersample`` times the resolution and
box-filtering it down: supersampling the whole frame would cost several times more and
the figure is what participants judge. The video writer and the contact sheet share this
class, so both show exactly the same pictures.
"""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

from generation.motion.types import Motion
from generation.render.camera import Camera, character_size
from generation.render.floor import FloorGrid
from generation.render.figure import LEFT, RIGHT, body_root_index, figure_bones, hidden_joints, joint_sides
from generation.render.style import Style

REFERENCE_HEIGHT = 480  # Style widths are pixels at this frame height and scale with it
# A stimulus lasts seconds and a gallery clip a minute or two; a motion longer than this
# (a wrong frame time, say) would have the renderer plan gigabytes of frames.
MAX_VIDEO_SECONDS = 3600.0
# How far (a share of the frame's half-height at the camera's target) a figure may stray from
# the control path the camera follows before the camera follows the figure instead: far
# enough that every clip of a control that keeps near its path is filmed from the same
# places, near enough that one that strays (a mismatched clip) stays in frame to its end.
IN_VIEW_SHARE = 1.0


def frame_indices(n_frames: int, fps: float, out_fps: float) -> np.ndarray:
    """Source frame shown at each output frame when resampling by time (nearest frame)."""
    n_out = max(1, int(np.floor(n_frames * out_fps / fps + 0.5)))
    times = np.arange(n_out) / out_fps
    return np.minimum(np.floor(times * fps + 0.5).astype(np.int64), n_frames - 1)


def floor_path(motion: Motion, root_path: np.ndarray | None = None) -> np.ndarray:
    """The character's floor trajectory (T, 2) as x, z: ``root_path`` or the body root's."""
    if root_path is None:
        return motion.positions[:, body_root_index(motion.skeleton)][:, [0, 2]]
    return floor_points(root_path, motion.n_frames, "root_path")


def floor_points(points: np.ndarray, n_frames: int, name: str) -> np.ndarray:
    """A path given per motion frame as (T, 2) x, z or (T, 3) x, y, z -> (T, 2) x, z."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or len(points) != n_frames or points.shape[1] not in (2, 3):
        raise ValueError(
            f"{name} must have shape ({n_frames}, 2) as x, z or ({n_frames}, 3) "
            f"as x, y, z, one point per frame of the motion, got {points.shape}"
        )
    if not np.isfinite(points).all():
        raise ValueError(f"{name} contains NaN or infinity")
    return points if points.shape[1] == 2 else points[:, [0, 2]]


def kept_in_view(path: np.ndarray, figure: np.ndarray, reach: float) -> np.ndarray:
    """The floor points (T, 2) a camera following ``path`` aims at so that ``figure`` (T, 2)
    is never farther than ``reach`` from them: the path itself while the figure is that
    near, else moved towards the figure by as much as it strays beyond."""
    offset = figure - path
    distance = np.linalg.norm(offset, axis=-1, keepdims=True)
    beyond = np.clip(1.0 - reach / np.maximum(distance, 1e-9), 0.0, None)
    return path + offset * beyond


def on_floor(xz: np.ndarray) -> np.ndarray:
    """Floor points (..., 2) as x, z -> world points (..., 3) at y = 0."""
    return np.stack([xz[..., 0], np.zeros(xz.shape[:-1]), xz[..., 1]], axis=-1)


class FrameDrawer:
    """Draws the frames of one motion for one camera, size, frame rate and style.

    ``control_path`` (T, 2) x, z, one point per motion frame, is the floor path a control
    asks for (``PathControl.path().xz``), drawn under the root path. With it the camera
    tracks the control's path instead of the figure, so every system's clip of one
    control is filmed from the same places and draws the control identically: only
    the figure differs, and a figure that strays from its path is seen to stray. A
    figure that strays farther than the frame holds pulls the camera after it
    (``kept_in_view``), so that it is in frame for the whole clip.
    """

    def __init__(
        self,
        motion: Motion,
        camera: Camera = Camera(),
        size: tuple[int, int] = (640, 480),
        fps: float | None = None,
        root_path: np.ndarray | None = None,
        style: Style = Style(),
        control_path: np.ndarray | None = None,
    ) -> None:
        width, height = size
        if width < 1 or height < 1:
            raise ValueError(f"size must be positive, got {size}")
        camera = camera.framing(character_size(motion))
        self.size, self.camera, self.style = (int(width), int(height)), camera, style
        self.fps = float(fps) if fps is not None else float(motion.fps)
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be positive and finite, got {fps}")
        if not motion.duration <= MAX_VIDEO_SECONDS:
            raise ValueError(f"the motion lasts {motion.duration:g} s ({motion.n_frames} frames at {motion.fps:g} fps); "
                             f"videos are at most {MAX_VIDEO_SECONDS:g} s")
        self.scale = height / REFERENCE_HEIGHT

        self.source = frame_indices(motion.n_frames, motion.fps, self.fps)
        path = floor_path(motion, root_path)
        self.path = on_floor(path)  # every source frame, so the drawn path stays smooth
        figure_path = motion.positions[:, body_root_index(motion.skeleton)][:, [0, 2]]
        if control_path is None:
            self.control = None
            tracked = figure_path
        else:
            control = floor_points(control_path, motion.n_frames, "control_path")
            self.control = on_floor(control)
            tracked = kept_in_view(control, figure_path, IN_VIEW_SHARE * camera.distance * np.tan(
                np.radians(camera.fov) / 2))
        self.targets = camera.targets(tracked, motion.fps)[self.source]

        skeleton = motion.skeleton
        colours = {LEFT: style.bone_left, RIGHT: style.bone_right}
        self.joint_colours = [colours.get(side, style.bone) for side in joint_sides(skeleton)]
        self.bones = np.array(figure_bones(skeleton), dtype=np.int64).reshape(-1, 2)
        hidden = hidden_joints(skeleton)
        self.loose_joints = [  # joints in no drawn bone still get a dot
            j for j in range(skeleton.n_joints) if j not in hidden and j not in self.bones
        ]
        self.shown_joints = np.array(
            [j for j in range(skeleton.n_joints) if j not in hidden], dtype=np.int64
        )

        # Every joint of every output frame in one projection.
        joints = motion.positions[self.source]
        self.joints_cam = camera.to_camera(joints, self.targets)
        self.shadow_cam = camera.to_camera(on_floor(joints[..., [0, 2]]), self.targets)
        # Far bones first so nearer limbs are drawn over them.
        bone_depth = self.joints_cam[:, self.bones, 2].mean(axis=-1)
        self.bone_order = np.argsort(-bone_depth, axis=1, kind="stable")

        self.grid = FloorGrid(camera, self.size, style.grid_spacing, style.grid_width * self.scale)
        # Grid coverage 0..255 -> colour, applied in C through an image palette.
        background, grid = np.array(style.background), np.array(style.grid)
        ramp = background + (grid - background) * np.arange(256)[:, None] / 255
        self.grid_palette = np.floor(ramp + 0.5).astype(np.uint8).ravel().tolist()
        if not camera.follow:  # the floor looks the same in every frame: draw it once
            self.background = self._floor(self.targets[0])

    def __len__(self) -> int:
        return len(self.source)

    def image(self, k: int) -> Image.Image:
        """Output frame ``k`` as a PIL image of ``size``."""
        style, target, now = self.style, self.targets[k], int(self.source[k])
        canvas = self._floor(target) if self.camera.follow else self.background.copy()
        draw = ImageDraw.Draw(canvas)
        if self.control is not None:  # whole, as the task it sets: the part due by now darker
            self._draw_path(draw, self.control[now:], target, style.control_future, style.control_width)
            self._draw_path(draw, self.control[: now + 1], target, style.control_past, style.control_width)
        if style.draw_future_path:
            self._draw_path(draw, self.path[now:], target, style.path_future, style.path_width)
        self._draw_path(draw, self.path[: now + 1], target, style.path_past, style.path_width)
        self._draw_figure(canvas, k)
        return canvas

    def frame(self, k: int) -> np.ndarray:
        """Output frame ``k`` as an (h, w, 3) uint8 array."""
        return np.asarray(self.image(k))

    def _px(self, width: float, supersample: int = 1) -> int:
        """A style width in drawing pixels: scaled with the frame, never under one output pixel."""
        return max(supersample, int(round(width * self.scale * supersample)))

    def _segments_px(self, segments: np.ndarray, target: np.ndarray) -> np.ndarray:
        """World segments (N, 2, 3) -> pixel segments (M, 4) of what survives near clipping."""
        cam = self.camera.to_camera(segments.reshape(-1, 3), target).reshape(segments.shape)
        a, b, keep = self.camera.clip_segments(cam[:, 0], cam[:, 1])
        pixels = self.camera.to_pixels(np.stack([a[keep], b[keep]], axis=1), self.size)
        return pixels.reshape(-1, 4)

    def _floor(self, target: np.ndarray) -> Image.Image:
        """The background with the floor grid seen from ``target``, as a new RGB image."""
        floor = Image.fromarray(self.grid.coverage_image(target))
        floor.putpalette(self.grid_palette)  # turns the "L" coverage into a "P" image
        return floor.convert("RGB")

    def _draw_path(self, draw: ImageDraw.ImageDraw, points: np.ndarray, target: np.ndarray, colour,
                   width: float) -> None:
        if len(points) < 2:
            return
        segments = self._segments_px(np.stack([points[:-1], points[1:]], axis=1), target)
        if len(segments) == len(points) - 1:  # nothing clipped: one polyline is much faster
            lines = [np.concatenate([segments[:, :2], segments[-1:, 2:]]).ravel().tolist()]
        else:
            lines = segments.tolist()
        # A half-tone rim one pixel wider softens the staircase of an aliased line cheaply.
        rim = tuple((np.add(colour, self.style.background) + 1) // 2)
        width = self._px(width)
        for line_width, line_colour in ((width + 1, rim), (width, colour)):
            for line in lines:
                draw.line(line, fill=line_colour, width=line_width)

    def _draw_figure(self, canvas: Image.Image, k: int) -> None:
        """Shadow, bones and joints of frame ``k``, supersampled inside their bounding box."""
        style, camera, s = self.style, self.camera, self.style.supersample
        bone_width, radius = self._px(style.bone_width, s), style.joint_radius * self.scale * s

        cam = self.joints_cam[k]
        a, b, keep = camera.clip_segments(cam[self.bones[:, 0]], cam[self.bones[:, 1]])
        bones_px = camera.to_pixels(np.stack([a, b], axis=1), self.size)
        joints_px = camera.to_pixels(cam, self.size)
        visible = cam[:, 2] >= camera.near
        if style.draw_shadow:
            sa, sb, shadow_keep = camera.clip_segments(
                self.shadow_cam[k, self.bones[:, 0]], self.shadow_cam[k, self.bones[:, 1]]
            )
            shadow_px = camera.to_pixels(np.stack([sa, sb], axis=1), self.size)
        else:
            shadow_px, shadow_keep = bones_px[:0], keep[:0]

        drawn = np.concatenate([
            bones_px[keep].reshape(-1, 2),
            shadow_px[shadow_keep].reshape(-1, 2),
            joints_px[self.shown_joints][visible[self.shown_joints]],
        ])  # fmt: skip
        if len(drawn) == 0:
            return
        pad = np.ceil(max(bone_width, 2 * radius) / s) + 2
        left, top = np.maximum(np.floor(drawn.min(axis=0) - pad), 0).astype(int)
        right, bottom = np.minimum(np.ceil(drawn.max(axis=0) + pad), self.size).astype(int)
        if left >= right or top >= bottom:
            return  # the figure is entirely off screen

        box = (left, top, right, bottom)
        layer = canvas.crop(box)
        if s > 1:
            layer = layer.resize((layer.width * s, layer.height * s), Image.NEAREST)
        draw = ImageDraw.Draw(layer)
        # Output pixel i spans supersampled pixels s*i .. s*i + s-1, centred at s*i + (s-1)/2.
        origin = np.array([left, top]) * s - (s - 1) / 2
        shadow_px = (shadow_px[shadow_keep] * s - origin).reshape(-1, 4).tolist()
        bones_px = (bones_px * s - origin).reshape(-1, 4).tolist()
        joints_px = (joints_px * s - origin).tolist()
        visible = visible.tolist()

        for segment in shadow_px:
            draw.line(segment, fill=style.shadow, width=bone_width)

        def dot(j: int) -> None:
            if visible[j]:
                x, y = joints_px[j]
                draw.ellipse((x - radius, y - radius, x + radius, y + radius), fill=self.joint_colours[j])

        for j in self.loose_joints:
            dot(j)
        keep, bones = keep.tolist(), self.bones.tolist()
        # Each bone is followed by its end dots so the depth order covers the joints too.
        for i in self.bone_order[k].tolist():
            if keep[i]:
                draw.line(bones_px[i], fill=self.joint_colours[bones[i][1]], width=bone_width)
                dot(bones[i][0])
                dot(bones[i][1])

        if s > 1:
            layer = layer.reduce(s)
        canvas.paste(layer, box[:2])
