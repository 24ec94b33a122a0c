"""What several command groups share: the camera arguments of every rendering command."""

from __future__ import annotations

import argparse

from ..render import Camera


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 640x480, got {text!r}") from None
    return width, height


def add_camera_arguments(parser: argparse.ArgumentParser) -> None:
    """The camera of the rendered clips, the same options for every command that renders."""
    default = Camera()
    group = parser.add_argument_group("camera (keep it the same for every system of a study)")
    group.add_argument("--azimuth", type=float, default=default.azimuth, help="degrees about the vertical (default %(default)s)")
    group.add_argument("--elevation", type=float, default=default.elevation, help="degrees above the horizon (default %(default)s)")
    group.add_argument("--distance", type=float, default=default.distance, help="cm from the character (default %(default)s)")
    group.add_argument("--size", type=_size, default=(640, 480), help="frame size WIDTHxHEIGHT (default 640x480)")
    group.add_argument("--fps", type=float, default=20.0, help="frame rate of the video (default %(default)s)")


def camera_from(args: argparse.Namespace) -> Camera:
    return Camera(azimuth=args.azimuth, elevation=args.elevation, distance=args.distance)
