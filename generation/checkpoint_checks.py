"""What a checkpoint's description must satisfy before a model is built from it or sampled.

Researchers upload checkpoints to the study app, so a checkpoint is input like any other
and may describe anything. ``check_description`` reads the JSON half only (no torch): a
positive, finite frame rate, standardisation statistics that are finite, positive where
they divide and as long as the model's features, a skeleton with joints. The model is
checked against the file's tensors as it is built (``generation.build_budget``), and the
tensors' values as they are read (``generation.store``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .motion.dataset_options import DatasetOptions
from .motion.types import Skeleton
from .store import CheckpointError


def _numbers(values: object) -> list[float] | None:
    if not isinstance(values, list) or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return None
    return [float(v) for v in values]


def check_description(path: Path, kind_needs_control: bool, pose_dim: int, control_dim: int,
                      features: dict, stats: dict, skeleton: dict) -> None:
    """The checkpoint's JSON fields make sense together (see the module docstring)."""
    try:
        DatasetOptions.from_dict(features["dataset_options"])
    except KeyError:
        raise CheckpointError(f"{path}: features.dataset_options is missing") from None
    except (TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: features.dataset_options: {error}") from None
    expected = {"pose": pose_dim, **({"control": control_dim} if kind_needs_control else {})}
    for name, size in expected.items():
        if not isinstance(stats.get(name), dict):
            raise CheckpointError(f"{path}: stats.{name} is missing (the standardisation of the {name} features)")
        for field in ("mean", "std"):
            values = _numbers(stats[name].get(field))
            if values is None:
                raise CheckpointError(f"{path}: stats.{name}.{field} must be a list of numbers")
            if len(values) != size:
                raise CheckpointError(f"{path}: stats.{name}.{field} has {len(values)} values; the model's "
                                      f"{name} features have {size}")
            if not all(math.isfinite(v) for v in values):
                raise CheckpointError(f"{path}: stats.{name}.{field} holds NaN or infinity")
            if field == "std" and min(values) <= 0:
                raise CheckpointError(f"{path}: stats.{name}.std must be positive, holds {min(values):g}")
    if not skeleton.get("names"):
        raise CheckpointError(f"{path}: skeleton has no joints")
    try:
        joints = Skeleton.from_dict(skeleton)
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: skeleton: {type(error).__name__}: {error}") from None
    if not np.isfinite(joints.offsets).all():
        raise CheckpointError(f"{path}: skeleton offsets hold NaN or infinity")
