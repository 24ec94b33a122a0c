"""Motion for any skeleton: BVH in and out, forward and inverse kinematics, features, resampling;
``data/`` makes training data of it (files and labels, splits, datasets, takes, augmentation)."""

from .bvh import BVH, BVHError, load_motion, motion_to_bvh, read_bvh, write_bvh
from .types import Motion, Skeleton

__all__ = [
    "BVH",
    "BVHError",
    "Motion",
    "Skeleton",
    "load_motion",
    "motion_to_bvh",
    "read_bvh",
    "write_bvh",
]
