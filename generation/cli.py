"""Command line of the generation package: ``python -m generation COMMAND --help``.

  info PATH             describe a BVH file or a dataset (.npz)
  build-dataset FOLDER  encode a folder of BVH files into a cached training set
  render BVH...         draw clips as MP4 stick figures (and contact sheets)
  gallery FOLDER        render a few natural clips per content, with an index.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .motion.bvh import BVHError, read_bvh
from .motion.dataset import DatasetOptions, MotionDataset, build_dataset, default_cache_dir
from .motion.kinematics import subtree_motion
from .motion.resample import resample
from .motion.root import RootOptions, hips_index, root_trajectory


def _size(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like 640x480, got {text!r}") from None
    return width, height


def _add_camera_arguments(parser: argparse.ArgumentParser) -> None:
    from .render import Camera

    default = Camera()
    group = parser.add_argument_group("camera (keep it the same for every system of a study)")
    group.add_argument("--azimuth", type=float, default=default.azimuth, help="degrees about the vertical (default %(default)s)")
    group.add_argument("--elevation", type=float, default=default.elevation, help="degrees above the horizon (default %(default)s)")
    group.add_argument("--distance", type=float, default=default.distance, help="cm from the character (default %(default)s)")
    group.add_argument("--size", type=_size, default=(640, 480), help="frame size WIDTHxHEIGHT (default 640x480)")
    group.add_argument("--fps", type=float, default=20.0, help="frame rate of the video (default %(default)s)")


def _camera(args: argparse.Namespace):
    from .render import Camera

    return Camera(azimuth=args.azimuth, elevation=args.elevation, distance=args.distance)


def info(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if path.suffix.lower() == ".npz":
        dataset = MotionDataset.load(path)
        for split in ("train", "test"):
            clips = dataset.select(split)
            windows = dataset.windows(split, standardize=False)["pose"]
            print(f"{split}: {len(clips)} clips ({len(dataset.select(split, augmented=False))} takes), {len(windows)} windows")
        print(f"skeleton: {dataset.skeleton.n_joints} joints; pose {dataset.arrays['pose'].shape[1]}-D, angles {dataset.angle_spec.size}-D")
        print("options:", json.dumps(dataset.options.to_dict()))
        return 0
    bvh = read_bvh(path)
    motion = bvh.to_motion()
    print(f"{path}: {len(bvh.values)} frames at {bvh.fps:g} fps ({motion.duration:.2f} s), {bvh.skeleton.n_joints} joints, {bvh.values.shape[1]} channels")
    for j, name in enumerate(bvh.skeleton.names):
        parent = bvh.skeleton.names[bvh.skeleton.parents[j]] if bvh.skeleton.parents[j] >= 0 else "-"
        print(f"  {name:<24} parent {parent:<24} channels {' '.join(bvh.channels[j]) or '-'}")
    return 0


def build(args: argparse.Namespace) -> int:
    options = DatasetOptions(
        fps=args.fps,
        window_seconds=args.window,
        overlap=args.overlap,
        mirror=not args.no_mirror,
        reverse=args.reverse,
        contents=tuple(args.contents.split(",")) if args.contents else None,
        holdout_fraction=args.holdout,
        seed=args.seed,
        angle_representation=args.representation,
        scale=args.scale,
    )
    dataset = build_dataset(args.folder, options, cache_dir=args.cache_dir)
    if args.out:
        dataset.save(args.out)
    train, test = dataset.windows("train", standardize=False), dataset.windows("test", standardize=False)
    print(f"dataset {dataset.fingerprint[:12]}: {len(dataset.select('train', augmented=False))} training takes "
          f"({len(train['pose'])} windows of {options.window_frames} frames with augmentation), "
          f"{len(dataset.select('test'))} held-out takes ({len(test['pose'])} windows)")
    print(f"cached in {args.cache_dir or default_cache_dir()}" + (f"; saved to {args.out}" if args.out else ""))
    return 0


def render(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .motion.bvh import load_motion
    from .render import contact_sheet, render_video

    out = Path(args.out)
    if len(args.bvh) > 1 and out.suffix:
        raise ValueError("with several input files, --out must be a folder")
    camera = _camera(args)
    for source in tqdm(args.bvh, desc="rendering", unit="clip", disable=len(args.bvh) < 2):
        source = Path(source)
        motion = resample(load_motion(source), args.fps)
        motion = subtree_motion(motion, hips_index(motion.skeleton))
        target = out if out.suffix else out / f"{source.stem}.mp4"
        floor = root_trajectory(motion, RootOptions()).xz
        render_video(motion, target, camera=camera, size=args.size, root_path=floor)
        if args.sheet:
            contact_sheet(motion, target.with_suffix(".png"), camera=camera, root_path=floor)
        print(target)
    return 0


def gallery(args: argparse.Namespace) -> int:
    from .gallery import GalleryOptions, build_gallery

    options = GalleryOptions(
        fps=args.fps, seconds=args.seconds, size=args.size, per_content=args.per_content,
        contents=tuple(args.contents.split(",")) if args.contents else None, camera=_camera(args),
    )
    entries = build_gallery(args.folder, args.out, options)
    print(f"{len(entries)} clips in {args.out} (index.json lists them)")
    return 0


def parser() -> argparse.ArgumentParser:
    root = argparse.ArgumentParser(prog="python -m generation", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = root.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = commands.add_parser("info", help="describe a BVH file or a dataset .npz")
    p.add_argument("path", help="a .bvh file or a dataset .npz")
    p.set_defaults(run=info)

    p = commands.add_parser("build-dataset", help="encode a BVH folder into a cached training set",
                            description="Read every BVH file (and its JSON labels) in FOLDER, resample, augment the "
                                        "training takes, encode MoGlow and joint-angle features, split by take, and "
                                        "cache the result under a fingerprint of the inputs and options.")
    p.add_argument("folder", help="folder of .bvh files (or with a data/ subfolder of them)")
    p.add_argument("--out", help="also save the dataset to this .npz")
    p.add_argument("--cache-dir", help="where cached datasets live (default $MOTION_CACHE_DIR or var/cache)")
    p.add_argument("--fps", type=float, default=20.0, help="frame rate to resample to (default %(default)s)")
    p.add_argument("--window", type=float, default=4.0, help="window length in seconds (default %(default)s)")
    p.add_argument("--overlap", type=float, default=0.5, help="overlap of consecutive windows (default %(default)s)")
    p.add_argument("--no-mirror", action="store_true", help="do not add left-right mirrored copies")
    p.add_argument("--reverse", action="store_true", help="add time-reversed copies")
    p.add_argument("--contents", help="comma-separated content labels to keep, e.g. walk,run")
    p.add_argument("--holdout", type=float, default=0.1, help="fraction of each content's takes held out (default %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the held-out choice (default %(default)s)")
    p.add_argument("--representation", choices=("quaternion", "expmap"), default="quaternion", help="joint rotations as (default %(default)s)")
    p.add_argument("--scale", type=float, default=1.0, help="multiply lengths by this to get centimetres (default %(default)s)")
    p.set_defaults(run=build)

    p = commands.add_parser("render", help="render BVH clips to MP4 stick figures")
    p.add_argument("bvh", nargs="+", help="BVH files")
    p.add_argument("--out", "-o", required=True, help="an .mp4 path (one input) or a folder")
    p.add_argument("--sheet", action="store_true", help="also write a contact-sheet PNG beside each video")
    _add_camera_arguments(p)
    p.set_defaults(run=render)

    p = commands.add_parser("gallery", help="render a few natural clips per content label, with index.json")
    p.add_argument("folder", help="folder of .bvh files")
    p.add_argument("--out", "-o", required=True, help="folder for the videos, sheets and index.json")
    p.add_argument("--per-content", type=int, default=1, help="clips per content label (default %(default)s)")
    p.add_argument("--contents", help="comma-separated content labels to include")
    p.add_argument("--seconds", type=float, default=4.0, help="length of each clip (default %(default)s)")
    _add_camera_arguments(p)
    p.set_defaults(run=gallery)
    return root


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    except (BVHError, ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
