"""The camera: where it looks from, and world points to pixels.

The camera has a fixed orientation (azimuth, elevation) and distance; only its target
moves. Unless given, the distance and the target's height follow the character's size
(``framing``): the figure fills the same share of the frame whatever the rig, so a
child, a giant and motion capture in any unit look alike. In follow mode the target tracks the smoothed floor position of the character so
a walking figure stays in frame while the floor visibly slides past (the motion is still
readable against the grid). Everything is a pure function of the camera's fields and the
motion, so a study can store the camera as JSON and draw every system identically.

Conventions: world y is up, cm. Azimuth 0 puts the camera on the +z side looking towards
-z; positive azimuth swings it towards +x. Pixels have x right and y down.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from functools import cached_property

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..motion.types import Motion
from ..motion.skeleton_units import skeleton_size


@dataclass(frozen=True)
class Camera:
    azimuth: float = 35.0  # degrees about the vertical axis
    elevation: float = 18.0  # degrees above the horizon
    distance: float | None = None  # cm from the target; None: from the character's size and figure_share
    fov: float = 40.0  # vertical field of view, degrees
    target_height: float | None = None  # cm above the floor aimed at; None: target_share of the character's size
    follow: bool = True  # track the character; False aims at the clip's mean floor position
    follow_smoothing: float = 0.5  # s, Gaussian sigma that removes the gait's sway from tracking
    near: float = 10.0  # cm; geometry closer than this (or behind the camera) is clipped
    # The share of the frame's height that the character's size (foot-to-head chain,
    # ``skeleton_size``) spans at the target: a drawn Bandai-Namco walker fills about 43 %.
    figure_share: float = 0.48
    target_share: float = 0.58  # of the character's size above the floor: about the hips

    def __post_init__(self) -> None:
        if not -90.0 < self.elevation < 90.0:
            raise ValueError(f"elevation must be strictly between -90 and 90, got {self.elevation}")
        if not 0.0 < self.fov < 180.0:
            raise ValueError(f"fov must be between 0 and 180 degrees, got {self.fov}")
        if not 0.0 < self.near < (self.distance if self.distance is not None else math.inf):
            raise ValueError(f"need 0 < near < distance, got near={self.near}, distance={self.distance}")
        if not (0.0 < self.figure_share and 0.0 <= self.target_share):
            raise ValueError(f"figure_share must be positive and target_share not negative, "
                             f"got {self.figure_share} and {self.target_share}")
        if self.follow_smoothing < 0:
            raise ValueError(f"follow_smoothing must be >= 0, got {self.follow_smoothing}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Camera":
        unknown = set(data) - {f.name for f in fields(cls)}
        if unknown:
            raise ValueError(f"unknown Camera fields: {', '.join(sorted(unknown))}")
        return cls(**data)

    def framing(self, character_size: float) -> "Camera":
        """This camera with the distance and target height it leaves open (None) set for a
        character of ``character_size`` cm (see ``character_size``)."""
        if not (math.isfinite(character_size) and character_size > 0):
            raise ValueError(f"the character's size must be a positive number of cm, got {character_size}")
        half_view = np.tan(np.radians(self.fov) / 2)
        distance = character_size / (2 * self.figure_share * half_view) if self.distance is None else self.distance
        height = self.target_share * character_size if self.target_height is None else self.target_height
        return replace(self, distance=max(float(distance), 2 * self.near), target_height=float(height))

    def _framed(self) -> None:
        if self.distance is None or self.target_height is None:
            raise ValueError("the camera's distance and target height follow the character: call framing() first")

    @cached_property  # the orientation never changes, and projection runs several times a frame
    def rotation(self) -> np.ndarray:
        """(3, 3) world-to-camera rotation; rows are the camera's right, up and forward axes."""
        az, el = np.radians(self.azimuth), np.radians(self.elevation)
        backward = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        forward = -backward
        right = np.cross(forward, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return np.stack([right, up, forward])

    def eye_offset(self) -> np.ndarray:
        """The camera position relative to its target (3,)."""
        self._framed()
        return -self.distance * self.rotation[2]

    def focal_length(self, height: int) -> float:
        """Focal length in pixels for an image ``height`` pixels tall."""
        return 0.5 * height / np.tan(np.radians(self.fov) / 2)

    def targets(self, floor_path: np.ndarray, fps: float) -> np.ndarray:
        """Per-frame look-at points (T, 3) for a character whose floor path is (T, 2) x, z."""
        self._framed()
        floor_path = np.asarray(floor_path, dtype=np.float64)
        if self.follow:
            sigma = self.follow_smoothing * fps
            xz = gaussian_filter1d(floor_path, sigma, axis=0, mode="nearest") if sigma > 0 else floor_path
        else:
            xz = np.broadcast_to(floor_path.mean(axis=0), floor_path.shape)
        return np.stack([xz[:, 0], np.full(len(xz), self.target_height), xz[:, 1]], axis=1)

    def to_camera(self, points: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """World points (..., N, 3) seen from targets (..., 3) -> camera coordinates (..., N, 3).

        Camera coordinates are (right, up, depth); depth is the distance along the view axis.
        """
        eyes = np.asarray(targets, dtype=np.float64) + self.eye_offset()
        return (np.asarray(points, dtype=np.float64) - eyes[..., None, :]) @ self.rotation.T

    def to_pixels(self, camera_points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
        """Perspective-divide camera coordinates (..., 3) to pixels (..., 2) for size (w, h).

        Integer coordinates are pixel centres, as in PIL. Only meaningful where depth >= near;
        callers clip first (see ``clip_segments``).
        """
        width, height = size
        f = self.focal_length(height)
        depth = np.maximum(camera_points[..., 2], self.near)  # keeps clipped points finite
        x = 0.5 * (width - 1) + f * camera_points[..., 0] / depth
        y = 0.5 * (height - 1) - f * camera_points[..., 1] / depth
        return np.stack([x, y], axis=-1)

    def project(
        self, points: np.ndarray, targets: np.ndarray, size: tuple[int, int]
    ) -> tuple[np.ndarray, np.ndarray]:
        """World points (..., N, 3) -> (pixels (..., N, 2), visible (..., N) bool)."""
        cam = self.to_camera(points, targets)
        return self.to_pixels(cam, size), cam[..., 2] >= self.near

    def clip_segments(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Clip camera-space segments a-b (..., 3) to the near plane.

        Returns the clipped endpoints and a mask of segments with anything left in front of
        the camera; a segment crossing the plane is cut where it crosses, so lines running
        past the camera (floor grid, long paths) stay correct instead of flipping through
        the projection's singularity.
        """
        da, db = a[..., 2] - self.near, b[..., 2] - self.near
        keep = (da >= 0) | (db >= 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip(da / (da - db), 0.0, 1.0)[..., None]  # where the segment meets the plane
        crossing = a + t * (b - a)
        a = np.where((da < 0)[..., None], crossing, a)
        b = np.where((db < 0)[..., None], crossing, b)
        return a, b, keep


def character_size(motion: Motion) -> float:
    """How tall the character is (cm), for framing: its skeleton's foot-to-head chain, or
    for rigs whose legs are not named by side, the median height of the figure."""
    try:
        return skeleton_size(motion.skeleton)
    except ValueError:
        heights = motion.positions[..., 1].max(axis=1) - motion.positions[..., 1].min(axis=1)
        return max(float(np.median(heights)), 1.0)
