"""Building blocks of the study tests: a small real-clip folder and tiny MoGlow checkpoints.

The checkpoints are trained for real on real clips, just small enough to take seconds.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from generation import models
from generation.motion.dataset import DatasetOptions, build_dataset
from generation.train import TrainOptions, train

# Two walking and two running takes hold one of each out (the default 10 % rounds up to one per content).
CLIPS = ["walk_normal_001", "walk_happy_001", "walk_old_002", "run_normal_001", "run_happy_001"]


def link_clips(motion_data: Path, folder: Path) -> Path:
    """A BVH folder of ``CLIPS`` (symlinks into the real data) with its label files."""
    (folder / "data").mkdir(parents=True)
    for name in CLIPS:
        for suffix in (".bvh", ".json"):
            source = motion_data / "data" / f"dataset-1_{name}{suffix}"
            (folder / "data" / source.name).symlink_to(source)
    (folder / "cfg").symlink_to(motion_data / "cfg")
    return folder


def train_tiny_moglow(clips: Path, out: Path, steps: int, cache: Path) -> Path:
    """A MoGlow a few thousand parameters big, trained ``steps`` steps on the clips."""
    kind_class, make = models.MODELS["moglow"]
    tiny = dataclasses.replace(make("cpu"), steps=2, tau=3, lstm_hidden=16, batch_size=8, warmup_steps=0)
    dataset = build_dataset(clips, DatasetOptions(), cache_dir=cache, progress=False)
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(models.MODELS, "moglow", (kind_class, lambda name: tiny if name == "tiny" else make(name)))
        train("moglow", "tiny", dataset, out, TrainOptions(steps=steps, eval_every=steps), progress=False)
    return out
