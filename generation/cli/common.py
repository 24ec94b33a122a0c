"""What several command groups share: the camera arguments of every rendering command,
the control a rendered clip can draw on the floor, and the unit and rig arguments of
every command that reads BVH files."""

from __future__ import annotations

import argparse
import sys

from measures.units import parse_scale

from ..control import PRESETS, PathControl, load_control_file, preset_path
from ..motion.root import RootOptions
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
    group.add_argument("--distance", type=float, default=default.distance,
                       help="cm from the character (default: its foot-to-head length fills "
                            f"{default.figure_share * 100:.0f} %% of the frame's height)")
    group.add_argument("--size", type=_size, default=(640, 480), help="frame size WIDTHxHEIGHT (default 640x480)")
    group.add_argument("--fps", type=float, default=20.0, help="frame rate of the video (default %(default)s)")


def camera_from(args: argparse.Namespace) -> Camera:
    return Camera(azimuth=args.azimuth, elevation=args.elevation, distance=args.distance)


def shown_control(name: str, fps: float) -> PathControl:
    """The one path ``--draw-control`` names: a preset, or a JSON or YAML file holding one."""
    controls = [preset_path(name, fps)] if name in PRESETS else load_control_file(name, fps)
    if len(controls) != 1:
        raise ValueError(f"{name}: --draw-control draws one path; the file describes {len(controls)}")
    return controls[0]


def _scale(text: str) -> float | None:
    try:
        return parse_scale(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _pairs(text: str) -> dict[str, str]:
    pairs = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        left, colon, right = item.partition(":")
        if not (colon and left and right):
            raise argparse.ArgumentTypeError(f"mirror pairs look like LeftArm:RightArm,LeftLeg:RightLeg, got {item!r}")
        pairs[left] = right
    return pairs


def add_unit_arguments(parser: argparse.ArgumentParser, pairs: bool = True) -> None:
    """The files' unit and up axis (detected unless given) and, with ``pairs``, the
    left/right joints of rigs whose names follow no convention."""
    group = parser.add_argument_group("units and rig (everything is read into cm, y up)")
    group.add_argument("--scale", type=_scale, default=None, metavar="auto|UNIT|NUMBER",
                       help="the files' length unit: auto (from the skeleton's size), mm, cm, in, cmu (CMU's "
                            "5.64 cm), ft, m, or centimetres per unit (default auto)")
    group.add_argument("--up", choices=("auto", "y", "z"), default="auto",
                       help="the files' up axis (default auto: from the floor)")
    if pairs:
        group.add_argument("--mirror-pairs", type=_pairs, metavar="LEFT:RIGHT,...",
                           help="left and right joints for the facing and mirroring, where names follow no "
                                "convention (default: paired by name)")


def dataset_units(args: argparse.Namespace) -> dict:
    """The ``DatasetOptions`` fields that the unit and rig arguments set."""
    pairs = getattr(args, "mirror_pairs", None)
    return {"scale": args.scale, "up": up_axis(args), "mirror_pairs": pairs, "root": RootOptions(pairs=pairs)}


def chosen_contents(args: argparse.Namespace) -> tuple[str, ...] | None:
    """--contents, else every content (None): what ``build-dataset`` and ``natural`` read by
    default, so that natural's held-out takes are the held-out takes of the dataset built
    with the same options (the split holds out a share of each content chosen)."""
    return tuple(args.contents.split(",")) if args.contents else None


def up_axis(args: argparse.Namespace) -> str | None:
    return None if args.up == "auto" else args.up


def take_names(text: str) -> list[str]:
    """``--takes NAME,...``: the take names (file names without .bvh), at least one."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    if not names:
        raise argparse.ArgumentTypeError("name at least one take (file names, comma-separated)")
    return names


def warn(lines: list[str]) -> None:
    for line in lines:
        print(f"warning: {line}", file=sys.stderr)
