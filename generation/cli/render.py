"""Commands that draw natural motion: ``render`` (BVH clips to MP4) and ``gallery``."""

from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from ..control import in_control_frame
from ..gallery import GalleryOptions, build_gallery
from ..motion.clip_files import load_body_motion
from ..motion.root import RootOptions, root_trajectory
from ..motion.unit_detection import choose_units
from ..render import contact_sheet, render_video
from .common import add_camera_arguments, add_unit_arguments, camera_from, shown_control, up_axis


def render(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if len(args.bvh) > 1 and out.suffix:
        raise ValueError("with several input files, --out must be a folder")
    camera = camera_from(args)
    sources = [Path(source) for source in args.bvh]
    root = RootOptions(pairs=args.mirror_pairs)
    choice = choose_units(sources, args.scale, up_axis(args), root)
    print(choice.description)
    control = shown_control(args.draw_control, args.fps) if args.draw_control else None
    seconds = None if control is None else control.n_frames / args.fps
    for source in tqdm(sources, desc="rendering", unit="clip", disable=len(sources) < 2):
        motion = load_body_motion(source, args.fps, seconds, choice.units.scale, root, choice.units.up)
        target = out if out.suffix else out / f"{source.stem}.mp4"
        try:
            if control is not None:
                if motion.n_frames < control.n_frames:
                    raise ValueError(f"the take lasts {motion.n_frames} frames at {args.fps:g} fps, shorter "
                                     f"than the {control.n_frames} of the control it is to be drawn over")
                motion = in_control_frame(motion, root)  # starts where the control's path does
            floor = root_trajectory(motion, root).xz
        except ValueError as error:
            raise ValueError(f"{source}: {error}") from None
        drawn = {"root_path": floor, "control_path": None if control is None else control.path().xz}
        render_video(motion, target, camera=camera, size=args.size, **drawn)
        if args.sheet:
            contact_sheet(motion, target.with_suffix(".png"), camera=camera, **drawn)
        print(target)
    return 0


def gallery(args: argparse.Namespace) -> int:
    options = GalleryOptions(
        fps=args.fps, seconds=args.seconds, size=args.size, per_content=args.per_content,
        contents=tuple(args.contents.split(",")) if args.contents else None, camera=camera_from(args),
        scale=args.scale, up=up_axis(args),
    )
    entries = build_gallery(args.folder, args.out, options)
    print(f"{len(entries)} clips in {args.out} (index.json lists them)")
    return 0


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = commands.add_parser("render", help="render BVH clips to MP4 stick figures")
    p.add_argument("bvh", nargs="+", help="BVH files")
    p.add_argument("--out", "-o", required=True, help="an .mp4 path (one input) or a folder")
    p.add_argument("--sheet", action="store_true", help="also write a contact-sheet PNG beside each video")
    p.add_argument("--draw-control", metavar="CONTROL",
                   help="draw this control's path on the floor (a preset such as walk-circle, or a JSON or "
                        "YAML file describing one path), the camera following it: each clip is cut to the "
                        "control's length and moved to start where the path starts, at the origin facing "
                        "+z, so whether the motion follows the path can be seen")
    add_camera_arguments(p)
    add_unit_arguments(p)
    p.set_defaults(run=render)

    p = commands.add_parser("gallery", help="render a few natural clips per content label, with index.json")
    p.add_argument("folder", help="folder of .bvh files")
    p.add_argument("--out", "-o", required=True, help="folder for the videos, sheets and index.json")
    p.add_argument("--per-content", type=int, default=1, help="clips per content label (default %(default)s)")
    p.add_argument("--contents", help="comma-separated content labels to include")
    p.add_argument("--seconds", type=float, default=4.0, help="length of each clip (default %(default)s)")
    add_camera_arguments(p)
    add_unit_arguments(p, pairs=False)
    p.set_defaults(run=gallery)
