"""Commands on motion data: ``info`` (a BVH file or a dataset), ``build-dataset`` and ``natural``
(held-out natural clips exported like samples: the NAT system)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from tqdm import tqdm

from ..control import following_arrays, lead_in_frames
from ..motion.bvh import read_bvh
from ..motion.dataset import MotionDataset, build_dataset, default_cache_dir
from ..motion.dataset_options import DatasetOptions
from ..motion.npz import save_motion_npz
from ..motion.root import integrate, root_trajectory
from ..motion.splits import SPLITS
from ..motion.takes import natural_takes
from ..motion.unit_detection import choose_units
from ..render import render_video
from .common import (add_camera_arguments, add_unit_arguments, camera_from, chosen_contents, dataset_units, take_names,
                     up_axis, warn)


def info(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if path.suffix.lower() == ".npz":
        dataset = MotionDataset.load(path)
        for split in SPLITS:
            clips = dataset.select(split)
            windows = dataset.windows(split, standardize=False)["pose"]
            print(f"{split}: {len(clips)} clips ({len(dataset.select(split, augmented=False))} takes), {len(windows)} windows")
        print(f"skeleton: {dataset.skeleton.n_joints} joints; pose {dataset.arrays['pose'].shape[1]}-D, angles {dataset.angle_spec.size}-D")
        print("options:", json.dumps(dataset.options.to_dict()))
        return 0
    bvh = read_bvh(path)
    choice = choose_units([path], args.scale, up_axis(args))
    motion = bvh.to_motion(choice.units.scale, choice.units.up)
    print(choice.description)
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
        contents=chosen_contents(args),
        holdout_fraction=args.holdout,
        validation_fraction=args.validation,
        seed=args.seed,
        angle_representation=args.representation,
        **dataset_units(args),
    )
    dataset = build_dataset(args.folder, options, cache_dir=args.cache_dir)
    warn(dataset.window_warnings())
    dataset.require_training_windows()
    if args.out:
        dataset.save(args.out)
    windows = {split: len(dataset.windows(split, standardize=False)["pose"]) for split in SPLITS}
    print(f"dataset {dataset.fingerprint[:12]}: {len(dataset.select('train', augmented=False))} training takes "
          f"({windows['train']} windows of {options.window_frames} frames with augmentation), "
          f"{len(dataset.select('validation'))} validation takes ({windows['validation']} windows), "
          f"{len(dataset.select('test'))} held-out test takes ({windows['test']} windows)")
    print(f"cached in {args.cache_dir or default_cache_dir()}" + (f"; saved to {args.out}" if args.out else ""))
    return 0


def natural_command(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        raise ValueError(f"--seconds must be a positive number, not {args.seconds}")
    options = DatasetOptions(contents=None if args.takes else chosen_contents(args), holdout_fraction=args.holdout,
                             seed=args.seed, **dataset_units(args))
    takes, options = natural_takes(args.folder, options, args.takes, args.split, progress=True)
    lead = lead_in_frames(args.lead_in, options.fps)
    frames = int(round(args.seconds * options.fps))
    out = Path(args.out)
    written, short = 0, []
    for take in tqdm(takes, desc="natural clips", unit="clip", disable=len(takes) < 2):
        if take.motion.n_frames < lead + 2:  # as held-out control leaves it out
            continue
        motion = take.clip(args.seconds, args.lead_in)
        if motion.n_frames < frames:
            short.append(take.name)
        control = take.control[lead:lead + motion.n_frames]
        start = root_trajectory(motion, options.root)  # the take's control, from where the clip starts
        asked = integrate(control, options.fps, start.xz[0], start.yaw[0])
        save_motion_npz(motion, out / f"{take.name}.npz", **following_arrays(motion, asked, options.root))
        written += 1
        if args.render:
            floor = root_trajectory(motion, options.root).xz
            render_video(motion, out / f"{take.name}.mp4", camera=camera_from(args), size=args.size, root_path=floor)
    which = "named" if args.takes else args.split
    if not written:
        raise ValueError(f"no {which} take is longer than the lead-in of {args.lead_in:g} s")
    if short:
        warn([f"{len(short)} take(s) end before {args.lead_in + args.seconds:g} s, so their clips are shorter: "
              + ", ".join(short[:10]) + (f" and {len(short) - 10} more" if len(short) > 10 else "")])
    skipped = f" ({len(takes) - written} shorter than the lead-in left out)" if written < len(takes) else ""
    print(f"{written} natural {which} clips in {out}{skipped}")
    return 0


def add_natural_parser(commands: argparse._SubParsersAction) -> None:
    """The ``natural`` command's parser."""
    p = commands.add_parser("natural", help="export natural clips (held-out takes by default) like samples",
                            description="Write natural clips of FOLDER as npz (and optionally MP4), read exactly as "
                                        "the models' training data is: the NAT system of a study or of the objective "
                                        "metrics. The takes are those the seeded split that build-dataset and training "
                                        "make of the folder hold out, of every content by default as build-dataset "
                                        "reads it (each content's share is drawn on its own, so a model trained on "
                                        "some contents has its held-out takes among them; no model needs to have been "
                                        "trained on it), or the takes named with --takes.")
    p.add_argument("folder", nargs="+", help="folder of .bvh files; several are pooled (clip names must differ)")
    p.add_argument("--out", "-o", required=True, help="output folder")
    p.add_argument("--split", choices=("test", "train"), default="test", help="which takes (default: held-out)")
    p.add_argument("--takes", type=take_names, metavar="NAME,...",
                   help="these takes (file names without .bvh, comma-separated) instead of a split's, whatever "
                        "their content")
    p.add_argument("--contents", help="comma-separated content labels to keep (default: every content, as "
                                      "build-dataset's)")
    p.add_argument("--holdout", type=float, default=0.1,
                   help="fraction of each content's takes the split holds out, as build-dataset's (default "
                        "%(default)s, as train's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split, as build-dataset's (default %(default)s)")
    p.add_argument("--seconds", type=float, default=4.0, help="length of each clip (default %(default)s)")
    p.add_argument("--lead-in", type=float, default=0.0, metavar="SECONDS",
                   help="each clip starts SECONDS into its take, as `sample -c held-out --lead-in` samples it "
                        "(default %(default)s)")
    p.add_argument("--render", action="store_true", help="also render each clip to MP4")
    add_camera_arguments(p)
    add_unit_arguments(p)
    p.set_defaults(run=natural_command)


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = commands.add_parser("info", help="describe a BVH file or a dataset .npz")
    p.add_argument("path", help="a .bvh file or a dataset .npz")
    add_unit_arguments(p, pairs=False)
    p.set_defaults(run=info)

    p = commands.add_parser("build-dataset", help="encode a BVH folder into a cached training set",
                            description="Read every BVH file (and its JSON labels) in FOLDER, resample, augment the "
                                        "training takes, encode MoGlow and joint-angle features, split by take, and "
                                        "cache the result under a fingerprint of the inputs and options.")
    p.add_argument("folder", nargs="+", help="folder of .bvh files (or with a data/ subfolder of them); several are pooled")
    p.add_argument("--out", help="also save the dataset to this .npz")
    p.add_argument("--cache-dir", help="where cached datasets live (default $MOTION_CACHE_DIR or var/cache)")
    p.add_argument("--fps", type=float, default=20.0, help="frame rate to resample to (default %(default)s)")
    p.add_argument("--window", type=float, default=4.0, help="window length in seconds (default %(default)s)")
    p.add_argument("--overlap", type=float, default=0.5, help="overlap of consecutive windows (default %(default)s)")
    p.add_argument("--no-mirror", action="store_true", help="do not add left-right mirrored copies")
    p.add_argument("--reverse", action="store_true", help="add time-reversed copies")
    p.add_argument("--contents", help="comma-separated content labels to keep, e.g. walk,run")
    p.add_argument("--holdout", type=float, default=0.1,
                   help="fraction of each content's takes held out for testing (default %(default)s)")
    p.add_argument("--validation", type=float, default=0.1,
                   help="fraction of each content's other takes held out of training to choose checkpoints "
                        "(default %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="seed of the held-out choice (default %(default)s)")
    p.add_argument("--representation", choices=("quaternion", "expmap"), default="quaternion", help="joint rotations as (default %(default)s)")
    add_unit_arguments(p)
    p.set_defaults(run=build)
