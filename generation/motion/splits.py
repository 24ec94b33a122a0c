"""The seeded split of a folder's takes into training, validation and test: for each
content, a seeded fraction of its takes held out for testing, then of the others for
validation, the same split for every command that reads the folder with the same options."""

from __future__ import annotations

import hashlib
from pathlib import Path

from .dataset_options import DatasetOptions

SPLITS = ("train", "validation", "test")


def take_of(stem: str) -> str:
    """The take a file belongs to: its name without augmentation; one file is one take."""
    return stem


def split_takes(takes: list[tuple[str, str | None]], fraction: float, seed: int) -> set[str]:
    """The held-out takes: for each content, a seeded-random ``fraction`` (at least one
    when the content has two or more takes)."""
    by_content: dict[str | None, list[str]] = {}
    for take, content in takes:
        by_content.setdefault(content, []).append(take)
    held = set()
    for content, group in sorted(by_content.items(), key=lambda kv: str(kv[0])):
        group = sorted(set(group), key=lambda t: hashlib.sha256(f"{seed}:{t}".encode()).hexdigest())
        n = int(round(fraction * len(group)))
        if fraction > 0 and len(group) >= 2:
            n = max(1, min(n, len(group) - 1))
        held.update(group[:n])
    return held


def take_splits(files: list[Path], labels: dict[Path, tuple[str | None, str | None]],
                options: DatasetOptions) -> dict[str, str]:
    """The split ("train", "validation" or "test") of each file's take: a seeded
    fraction of each content's takes held out for testing, then of the others for
    validation (``split_takes``)."""
    takes = [(take_of(f.stem), labels[f][0]) for f in files]
    held_out = split_takes(takes, options.holdout_fraction, options.seed)
    validation = split_takes([t for t in takes if t[0] not in held_out], options.validation_fraction, options.seed + 1)
    return {take: "test" if take in held_out else "validation" if take in validation else "train" for take, _ in takes}


__all__ = ["SPLITS", "split_takes", "take_of", "take_splits"]
