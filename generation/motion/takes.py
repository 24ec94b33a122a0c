"""Natural takes of any folder of BVH files, without building a dataset or training a
model on it: the takes that the seeded split holds out (the very split ``build_dataset``,
and so ``train``, makes of that folder with the same options), or takes the researcher
names. Each is read as the models' data is: the body, in centimetres with y up, at the
dataset's frame rate, with its MoGlow control (``features.encode_positions``).

This is where natural motion (the NAT system) and held-out controls come from when no
checkpoint has been trained on the folder.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .clip_files import choose_files, cut_motion, find_bvh_files, load_body_motion, motion_folders, read_labels
from .dataset_options import DatasetOptions, with_units
from .splits import SPLITS, take_of, take_splits
from .features import encode_positions
from .types import Motion


@dataclass(frozen=True)
class NaturalTake:
    """One take of a folder as the models see it."""

    name: str  # the file's stem, which names the take
    path: Path
    content: str | None
    style: str | None
    motion: Motion  # the body, in cm with y up, at the options' frame rate
    control: np.ndarray  # (frames, 3) forward, sideways and yaw velocity, as a dataset holds it

    def clip(self, seconds: float | None = None, start: float = 0.0) -> Motion:
        """The positions of the ``seconds`` after ``start`` seconds into the take."""
        return cut_motion(self.motion, seconds, start, self.path)


def natural_takes(folder: str | os.PathLike | Sequence[str | os.PathLike], options: DatasetOptions = DatasetOptions(),
                  names: Sequence[str] | None = None, split: str = "test",
                  progress: bool = False) -> tuple[list[NaturalTake], DatasetOptions]:
    """The takes of ``split`` ("test": the held-out takes) of the folder(s) under
    ``options``' contents, seed and fractions, or the takes ``names`` names (file stems
    or names, whatever their content); and the options with the units as read.

    ValueError when no take is chosen, saying why.
    """
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; use one of {', '.join(SPLITS)}")
    if names:
        files = _named_files(folder, names)
        labels = {path: read_labels(path) for path in files}
    else:
        files, labels = choose_files(folder, options.contents)
        splits = take_splits(files, labels, options)
        files = [path for path in files if splits[take_of(path.stem)] == split]
        if not files:
            raise ValueError(_nothing_in(split, len(splits), options))
    options = with_units(files, options, progress)
    takes = []
    for path in files:
        motion = load_body_motion(path, options.fps, scale=options.scale, root=options.root, up=options.up)
        # Rounded as a dataset stores it, so that a take's control is the same whether it
        # was read here or from a dataset built on the folder.
        control = encode_positions(motion, options.root).control.astype(np.float32).astype(np.float64)
        takes.append(NaturalTake(path.stem, path, *labels[path], motion, control))
    return takes, options


def _named_files(folder, names: Sequence[str]) -> list[Path]:
    """The files of the named takes, in the order named; ValueError naming the unknown ones."""
    by_stem = {path.stem: path for path in find_bvh_files(folder)}
    wanted = [Path(name).stem if name.lower().endswith(".bvh") else name for name in names]
    unknown = [name for name in wanted if name not in by_stem]
    if unknown:
        folders = ", ".join(str(f) for f in motion_folders(folder))
        known = sorted(by_stem)
        listed = ", ".join(known[:10]) + (f" and {len(known) - 10} more" if len(known) > 10 else "")
        raise ValueError(f"no take named {', '.join(unknown)} in {folders}; its takes are {listed}")
    return [by_stem[name] for name in dict.fromkeys(wanted)]


def _nothing_in(split: str, takes: int, options: DatasetOptions) -> str:
    role = {"test": "held out", "validation": "held out for validation", "train": "left for training"}[split]
    return (f"no take of the {takes} is {role}: the split holds out {options.holdout_fraction:g} of each "
            "content's takes (one at least where a content has two or more, none of a content with one); "
            "name the takes instead")
