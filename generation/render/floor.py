"""The floor grid, computed per pixel instead of drawn as lines.

The camera only translates (its orientation and height are fixed), so the floor point
seen through each pixel is the camera's floor position plus a per-pixel offset that is
computed once per clip. A frame's grid is then a few vectorised operations: each pixel's
distance to the nearest grid line, in pixels, gives an antialiased line coverage, and
lines fade out towards the horizon before they become too dense to draw (moire).
Antialiased lines that slide smoothly also keep the H.264 encoder fast and the files
small when the camera follows a walker.
"""

from __future__ import annotations

import numpy as np

from generation.render.camera import Camera


class FloorGrid:
    """Grid line coverage of the y = 0 plane, for one camera and image size."""

    def __init__(self, camera: Camera, size: tuple[int, int], spacing: float, width: float) -> None:
        w, h = size
        self.size, self.spacing, self.half_width = size, spacing, width / 2
        # Each pixel centre's viewing ray in world coordinates.
        f = camera.focal_length(h)
        x = ((np.arange(w) + 0.5 - w / 2) / f).astype(np.float32)
        y = ((h / 2 - np.arange(h) - 0.5) / f).astype(np.float32)
        x, y = np.meshgrid(x, y)
        rays = np.stack([x, y, np.ones_like(x)], axis=-1) @ camera.rotation.astype(np.float32)
        eye_height = camera.target_height + camera.eye_offset()[1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.float32(-eye_height) / rays[..., 1]
        hits = np.isfinite(t) & (t > 0)
        t = np.where(hits, t, np.float32(0))
        offset_x, offset_z = t * rays[..., 0], t * rays[..., 2]  # floor point minus the eye's

        # Floor centimetres per pixel along x and z: converts distances to grid lines into
        # pixels (for antialiasing) and says where lines get too dense to draw.
        cm_per_px_x = np.hypot(*np.gradient(offset_x))
        cm_per_px_z = np.hypot(*np.gradient(offset_z))
        # Lines closer than ~4 px fade out; they would alias into moire.
        fade = np.clip(2.0 - 8.0 * np.maximum(cm_per_px_x, cm_per_px_z) / spacing, 0.0, 1.0)
        fade = np.where(hits, fade, np.float32(0))
        # Work on the rows that show any floor: one dense block is faster than fancy indexing.
        floor_rows = np.flatnonzero((fade > 0).any(axis=1))
        self.top = int(floor_rows[0]) if len(floor_rows) else h

        def block(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[self.top :], dtype=np.float32)

        self.offset_x, self.offset_z = block(offset_x / spacing), block(offset_z / spacing)
        # Coverage is computed in 0..255 steps directly, so scale the pixel distances once here.
        self.px_per_cell_x = block(255 * spacing / np.maximum(cm_per_px_x, 1e-9))
        self.px_per_cell_z = block(255 * spacing / np.maximum(cm_per_px_z, 1e-9))
        self.fade = block(fade)
        self.eye_offset = camera.eye_offset()

    def coverage_image(self, target: np.ndarray) -> np.ndarray:
        """(h, w) uint8 line coverage for a camera aimed at ``target``: 255 on a line, 0 off."""
        eye = np.asarray(target) + self.eye_offset
        full = np.float32(255 * (self.half_width + 0.5))
        lines = []
        for offset, px_per_cell, origin in (
            (self.offset_x, self.px_per_cell_x, eye[0]),
            (self.offset_z, self.px_per_cell_z, eye[2]),
        ):
            u = offset + np.float32(origin / self.spacing)
            u -= np.rint(u)
            np.abs(u, out=u)
            u *= px_per_cell  # 255 x pixels to the nearest line
            np.subtract(full, u, out=u)
            lines.append(u)
        coverage = np.maximum(lines[0], lines[1])
        np.clip(coverage, 0.0, 255.0, out=coverage)
        coverage *= self.fade
        image = np.zeros((self.size[1], self.size[0]), dtype=np.uint8)
        image[self.top :] = coverage
        return image
