"""How the figure, floor and path look: colours and line widths.

A study draws every system with one ``Style`` (and one ``Camera``), so it serialises to
JSON alongside the study's other parameters. Widths are in output pixels.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

RGB = tuple[int, int, int]


@dataclass(frozen=True)
class Style:
    background: RGB = (246, 245, 241)
    grid: RGB = (214, 212, 205)
    grid_spacing: float = 50.0  # cm between floor grid lines
    grid_width: float = 1.0
    bone: RGB = (45, 45, 52)  # spine, head and anything not named left or right
    bone_left: RGB = (35, 80, 165)
    bone_right: RGB = (175, 50, 45)
    bone_width: float = 4.0
    joint_radius: float = 3.5
    shadow: RGB = (205, 203, 196)  # the figure projected straight down onto the floor
    draw_shadow: bool = True
    path_past: RGB = (70, 130, 200)  # floor path up to the current frame
    path_future: RGB = (180, 200, 228)  # floor path still to come
    draw_future_path: bool = True
    path_width: float = 3.0
    # A control's path (drawn only when given): wider than the root path, which runs on
    # top of it, and warm where the root path is cool, so the two never blend.
    control_past: RGB = (214, 128, 38)  # the control's path up to the current frame
    control_future: RGB = (238, 196, 146)  # the control's path still to come
    control_width: float = 9.0
    supersample: int = 2  # the figure is drawn at this multiple, then box-filtered down (antialiasing)

    def __post_init__(self) -> None:
        if not isinstance(self.supersample, int) or self.supersample < 1:
            raise ValueError(f"supersample must be a positive integer, got {self.supersample!r}")
        if self.grid_spacing <= 0:
            raise ValueError(f"grid_spacing must be positive, got {self.grid_spacing}")

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Style":
        known = {f.name: f for f in fields(cls)}
        unknown = set(data) - set(known)
        if unknown:
            raise ValueError(f"unknown Style fields: {', '.join(sorted(unknown))}")
        # JSON turns colour tuples into lists; frozen dataclasses should hold tuples.
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})
