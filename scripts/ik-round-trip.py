"""How well inverse kinematics recovers real motion capture: the held-out takes of each
folder, read as the models see them (the body, at the models' frame rate), reduced to
joint positions, turned into rotations (``generation.motion.ik``), written as BVH and
read back by the project's reader.

    .venv/bin/python scripts/ik-round-trip.py [FOLDER ...] [--fps 20] [--all-takes]

Default folders: both Bandai-Namco folders beside the project. For each folder it prints
the joint error of the BVH's forward kinematics against the take's positions (mean over
every joint and frame, and the worst with where it is), the largest turn of any joint's
rotation between consecutive frames (against the take's own captured rotations), and
how fast the written Euler angles change (``euler_rate``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from generation.motion.bvh import load_motion, motion_to_bvh, read_bvh, write_bvh  # noqa: E402
from generation.motion.clip_files import find_bvh_files, load_body_motion, read_labels  # noqa: E402
from generation.motion.dataset_options import DatasetOptions  # noqa: E402
from generation.motion.splits import split_takes, take_of  # noqa: E402
from generation.motion.types import Motion  # noqa: E402
from generation.motion.unit_detection import choose_units  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
FOLDERS = [DATA / "bandai-namco-1", DATA / "bandai-namco-2-locomotion"]


def held_out_files(folder: Path, options: DatasetOptions) -> list[Path]:
    """The takes the dataset's seeded split holds out, over every content."""
    files = find_bvh_files(folder)
    held = split_takes([(take_of(f.stem), read_labels(f)[0]) for f in files], options.holdout_fraction, options.seed)
    return [f for f in files if take_of(f.stem) in held]


def turns(quaternions: np.ndarray) -> np.ndarray:
    """Degrees each joint's rotation turns between consecutive frames (frames - 1, J)."""
    dots = np.abs(np.sum(quaternions[1:] * quaternions[:-1], axis=-1))
    return np.degrees(2 * np.arccos(np.clip(dots, 0.0, 1.0)))


def euler_rate(bvh, quaternions: np.ndarray) -> tuple[float, float]:
    """The largest change of a written rotation channel between consecutive frames
    (degrees), and the largest ratio of such a change to the joint's turn over the
    cosine of its middle angle, which bounds how fast Euler angles that follow their
    rotation can move (a wrap or a swap of Euler triples would exceed it by far)."""
    rotation = [list(columns)[-3:] for columns in bvh.channel_columns()]
    euler = bvh.values[:, rotation]
    jumps = np.abs(np.diff(euler, axis=0)).max(axis=-1)
    cosine = np.minimum(*np.abs(np.cos(np.radians([euler[1:, :, 1], euler[:-1, :, 1]]))))
    moving = jumps > 1.0  # below a degree the ratio is rounding
    ratio = jumps[moving] / (turns(quaternions)[moving] / np.maximum(cosine[moving], 1e-3))
    return float(jumps.max()), float(ratio.max(initial=0.0))


def measure(folder: Path, fps: float, all_takes: bool) -> None:
    options = DatasetOptions()
    files = find_bvh_files(folder) if all_takes else held_out_files(folder, options)
    if not files:
        raise ValueError(f"{folder}: no held-out takes (the split holds out takes of contents that have two or "
                         "more); --all-takes measures every take")
    units = choose_units(files, None, None, options.root).units
    errors, worst, fastest, excess, jumps, rates = [], (0.0, ""), [], [], [], []
    with tempfile.TemporaryDirectory() as scratch:
        for path in files:
            take = load_body_motion(path, fps, scale=units.scale, root=options.root, up=units.up)
            written = write_bvh(motion_to_bvh(Motion(take.positions, take.fps, take.skeleton)),
                                Path(scratch) / path.name)
            again = load_motion(written)
            error = np.linalg.norm(again.positions - take.positions, axis=-1)
            errors.append(error.ravel())
            if error.max() > worst[0]:
                frame, joint = np.unravel_index(error.argmax(), error.shape)
                worst = (float(error.max()), f"{path.stem}, {take.skeleton.names[joint]}, frame {frame}")
            solved, captured = turns(again.rotations).max(), turns(take.rotations).max()
            fastest.append((solved, captured))
            excess.append(solved - captured)
            jump, rate = euler_rate(read_bvh(written), again.rotations)
            jumps.append(jump)
            rates.append(rate)
    errors = np.concatenate(errors)
    solved, captured = max(fastest)
    frames = len(errors) // take.skeleton.n_joints
    print(f"{folder.name}: {len(files)} {'' if all_takes else 'held-out '}takes, {frames} frames at {fps:g} fps")
    print(f"  joint error: mean {errors.mean():.2e} cm, worst {worst[0]:.2e} cm ({worst[1]})")
    print(f"  largest turn of a joint between frames: {solved:.1f} deg (that take's captured rotations: "
          f"{captured:.1f}); in any take at most {max(excess):+.1f} deg against the capture's fastest joint")
    print(f"  written Euler angles: largest change between frames {max(jumps):.1f} deg, at most {max(rates):.2f} "
          "times the joint's turn over the cosine of its middle angle")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="*", type=Path, default=FOLDERS)
    parser.add_argument("--fps", type=float, default=DatasetOptions().fps, help="frame rate to read the takes at")
    parser.add_argument("--all-takes", action="store_true", help="every take, not only the held-out ones")
    args = parser.parse_args()
    try:
        for folder in args.folders:
            measure(folder, args.fps, args.all_takes)
    except (ValueError, OSError) as error:  # BVHError is a ValueError naming the file and line
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
