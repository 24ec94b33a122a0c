"""The options that decide a dataset's contents (``DatasetOptions``, all part of its
fingerprint), checked before any file is read, and the units they leave open filled in
from the files (``with_units``)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from .root import RootOptions
from .unit_detection import choose_units

MAX_FPS = 1000.0  # motion capture runs at hundreds of frames per second at most


@dataclass(frozen=True)
class DatasetOptions:
    """Everything that decides the contents of a dataset (all part of its fingerprint)."""

    fps: float = 20.0
    window_seconds: float = 4.0
    overlap: float = 0.5
    mirror: bool = True
    reverse: bool = False
    contents: tuple[str, ...] | None = None  # keep only these content labels
    holdout_fraction: float = 0.1  # of the takes of each content, held out for testing
    # Of each content's remaining takes, held out for choosing checkpoints during training:
    # never trained on, and never reported, so held-out (test) figures stay unbiased.
    validation_fraction: float = 0.1
    seed: int = 0
    angle_representation: str = "quaternion"
    mirror_pairs: dict[str, str] | None = None
    scale: float | None = None  # file units to centimetres; None: detected when building
    root: RootOptions = field(default_factory=RootOptions)
    up: str | None = None  # the files' up axis, "y" or "z"; None: detected when building

    def __post_init__(self) -> None:
        # Checked here, before any file is read or cache written: each value below would
        # otherwise give a dataset that is silently wrong (no test takes, no windows) or
        # an error far from its cause.
        def refuse(name: str, rule: str) -> None:
            raise ValueError(f"dataset option {name} must be {rule}, got {getattr(self, name)!r}")

        if not (math.isfinite(self.fps) and 0 < self.fps <= MAX_FPS):
            refuse("fps", f"a number of frames per second above 0 and at most {MAX_FPS:g}")
        if not (math.isfinite(self.window_seconds) and self.window_seconds > 0) or self.window_frames < 2:
            refuse("window_seconds", f"long enough for two frames at {self.fps:g} fps")
        if not 0 <= self.overlap < 1:
            refuse("overlap", "at least 0 and below 1")
        for name in ("holdout_fraction", "validation_fraction"):
            if not 0 <= getattr(self, name) < 1:
                refuse(name, "at least 0 and below 1")
        if self.scale is not None and not (math.isfinite(self.scale) and self.scale > 0):
            refuse("scale", "a positive number (file units to centimetres)")

    @property
    def window_frames(self) -> int:
        return int(round(self.window_seconds * self.fps))

    @property
    def hop_frames(self) -> int:
        return max(1, int(round(self.window_frames * (1.0 - self.overlap))))

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "DatasetOptions":
        data = dict(data)
        data["root"] = RootOptions(**data["root"])
        data.setdefault("up", "y")  # recorded before the up axis was an option: y
        if data.get("contents") is not None:
            data["contents"] = tuple(data["contents"])
        return cls(**data)


def with_units(files: list[Path], options: DatasetOptions, progress: bool = False) -> DatasetOptions:
    """``options`` with the unit and up axis it leaves open (None) detected from
    ``files``; the choice is printed when ``progress`` is on."""
    choice = choose_units(files, options.scale, options.up, options.root)  # reads no file where both are given
    if progress:
        print(choice.description)
    return dataclasses.replace(options, scale=choice.units.scale, up=choice.units.up)


__all__ = ["MAX_FPS", "DatasetOptions", "with_units"]
