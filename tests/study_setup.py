"""Building blocks of the study tests: a small real-clip folder and tiny MoGlow checkpoints.

The checkpoints are trained for real on real clips, just small enough to take seconds.
"""

from __future__ import annotations

import functools
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch

from generation import registry
from generation.motion.clip_files import load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.render import render_video
from generation.train import TrainOptions, train

# Two walking and two running takes hold one of each out (the default 10 % rounds up to one per content).
CLIPS = ["walk_normal_001", "walk_happy_001", "walk_old_002", "run_normal_001", "run_happy_001"]


# For the label-controlled ERD: every style of a held-out take also among the training takes.
LABELLED_CLIPS = ["walk_normal_001", "walk_normal_002", "walk_happy_001", "walk_happy_002", "run_normal_001",
                  "run_happy_001"]


def link_clips(motion_data: Path, folder: Path, names: list[str] = CLIPS) -> Path:
    """A BVH folder of ``names`` (symlinks into the real data) with its label files."""
    (folder / "data").mkdir(parents=True)
    for name in names:
        for suffix in (".bvh", ".json"):
            source = motion_data / "data" / f"dataset-1_{name}{suffix}"
            (folder / "data" / source.name).symlink_to(source)
    (folder / "cfg").symlink_to(motion_data / "cfg")
    return folder


def train_tiny_moglow(clips: Path, out: Path, steps: int, cache: Path,
                      options: DatasetOptions = DatasetOptions()) -> Path:
    """A MoGlow a few thousand parameters big, trained ``steps`` steps on the clips prepared by ``options``."""
    cpu = registry.MODELS["moglow"].presets["cpu"]
    tiny = registry.Preset({**cpu.model, "steps": 2, "tau": 3, "lstm_hidden": 16},
                           {**cpu.training, "batch_size": 8, "warmup_steps": 0})
    dataset = build_dataset(clips, options, cache_dir=cache, progress=False)
    # A model this small gains nothing from a second thread and loses much when the cores are busy.
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setitem(registry.MODELS["moglow"].presets, "tiny", tiny)
            train("moglow", "tiny", dataset, out, TrainOptions(steps=steps, eval_every=steps), progress=False)
    finally:
        torch.set_num_threads(threads)
    return out


def train_tiny_erd(clips: Path, out: Path, cache: Path) -> Path:
    """A label-controlled model (ERD) a few thousand parameters big, trained a few steps on the clips."""
    from generation.hvrnn.data import load_attribute_data

    data = load_attribute_data(clips, cache_dir=cache, progress=False)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train("erd", "cpu", data, out, TrainOptions(steps=3, eval_every=3), progress=False,
              overrides={"encoder": (16,), "hidden": 16, "decoder": (16,), "batch_size": 2})
    finally:
        torch.set_num_threads(threads)
    return out


@functools.cache
def study_files(motion_data: Path, base: Path) -> SimpleNamespace:
    """Made once per test session under ``base``: the clip folder (``clips``), the dataset
    cache under ``root/var/cache``, a MoGlow trained 20 steps (``good``) and one trained 2
    (``early``, a BAD system), a label-controlled ERD trained on ``LABELLED_CLIPS``
    (``erd``, with ``labelled`` its folder), and a one-second rendered video (``video``)."""
    root = base / "study-files"
    clips = link_clips(motion_data, root / "clips")
    cache = root / "var" / "cache"
    good = train_tiny_moglow(clips, root / "moglow.safetensors", 20, cache)
    early = train_tiny_moglow(clips, root / "early.safetensors", 2, cache)
    video = render_video(load_body_motion(clips / "data" / f"dataset-1_{CLIPS[0]}.bvh", 20.0, 1.0),
                         root / "bad-example.mp4", size=(160, 120))
    erd = train_tiny_erd(link_clips(motion_data, root / "labelled-clips", LABELLED_CLIPS), root / "erd.safetensors", cache)
    return SimpleNamespace(root=root, clips=clips, labelled=root / "labelled-clips", good=good, early=early, erd=erd,
                           video=video)
