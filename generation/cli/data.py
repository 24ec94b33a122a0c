"""Commands on motion data: ``info`` (a BVH file or a dataset) and ``build-dataset``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..motion.bvh import read_bvh
from ..motion.dataset import SPLITS, DatasetOptions, MotionDataset, build_dataset, default_cache_dir
from ..motion.unit_detection import choose_units
from .common import add_unit_arguments, chosen_contents, dataset_units, up_axis, warn


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
