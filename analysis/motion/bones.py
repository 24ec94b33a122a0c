"""Bone-length error (MoGlow Table 3): how far generated joint positions stretch the skeleton.

Position-based models predict every joint freely, so nothing holds bones rigid. The
error is the root-mean-square difference, in cm, between each bone's length in every
frame and its reference length, the norm of the child's rest offset, over all bones and
frames. Natural motion driven by joint angles scores ~0.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from analysis.errors import AnalysisInputError


def rigid_bones(parents: Sequence[int], offsets: np.ndarray) -> list[tuple[int, int]]:
    """(parent, child) pairs whose length the skeleton fixes.

    Left out: bones of zero rest length (the joints coincide) and the bone out of a
    *reference root*, a root joint with zero offset and a single child. Such a root
    (e.g. Bandai-Namco's ``joint_Root`` on the floor) is a fixed origin and its child
    carries the character's global translation, so that "bone" has no fixed length.
    """
    parents = np.asarray(parents)
    offsets = np.asarray(offsets, dtype=np.float64)
    lengths = np.linalg.norm(offsets, axis=-1)
    root = int(np.flatnonzero(parents < 0)[0])
    reference_root = lengths[root] == 0 and int((parents == root).sum()) == 1
    return [(int(p), j) for j, p in enumerate(parents)
            if p >= 0 and lengths[j] > 0 and not (reference_root and p == root)]


def bone_length_rmse(clips: Sequence[np.ndarray], parents: Sequence[int], offsets: np.ndarray,
                     bones: Sequence[tuple[int, int]] | None = None) -> float:
    """RMSE (cm) of bone lengths against rest lengths over all clips, frames and bones.

    ``bones`` defaults to `rigid_bones`; ``clips`` is a sequence of (frames, joints, 3)
    arrays (or one (clips, frames, joints, 3) array).
    """
    bones = rigid_bones(parents, offsets) if bones is None else list(bones)
    if not bones:
        raise AnalysisInputError("the skeleton has no rigid bones to measure")
    parent_idx, child_idx = (np.array(side) for side in zip(*bones))
    reference = np.linalg.norm(np.asarray(offsets, dtype=np.float64)[child_idx], axis=-1)
    squared, count = 0.0, 0
    for clip in clips:
        clip = np.asarray(clip, dtype=np.float64)
        if clip.ndim != 3 or clip.shape[1] != len(parents):
            raise AnalysisInputError(
                f"clip positions must be (frames, {len(parents)}, 3), got {clip.shape}"
            )
        length = np.linalg.norm(clip[:, child_idx] - clip[:, parent_idx], axis=-1)
        squared += float(((length - reference) ** 2).sum())
        count += length.size
    return float(np.sqrt(squared / count))
