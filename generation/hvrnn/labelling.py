"""Labelling motion with the attribute classifiers (HVRNN Sec. 3.4 uses them to label
unlabelled data): the action and style they see in each clip of a BVH folder.

A clip longer than the classifiers' sequences is cut into the same equal pieces as
training data (``data.chunk_bounds``); its label is the class with the highest
probability averaged over the pieces, weighted by their lengths.
"""

from __future__ import annotations

import numpy as np

from ..motion.data.dataset import MotionDataset
from .classifiers import KINDS, AttributeClassifiers, predict
from .data import FPS, MAX_FRAMES, SequenceSet, chunk_bounds

UNKNOWN = -1  # the label index of a piece whose label is what is asked


def label_clips(classifiers: AttributeClassifiers, dataset: MotionDataset) -> list[dict]:
    """Per unaugmented clip with joint rotations: its name, its labels from the side file
    ("" where it has none), and the classifiers' action and style with their probabilities."""
    if abs(dataset.options.fps - FPS) > 1e-6:
        raise ValueError(f"the classifiers read {FPS:g} fps; this dataset is at {dataset.options.fps:g} fps")
    if dataset.angle_spec.size != classifiers.feature_dim:
        raise ValueError(f"the classifiers read {classifiers.feature_dim} angle features per frame; this data has "
                         f"{dataset.angle_spec.size} (another skeleton?)")
    clips = [c for c in dataset.clips if c.has_angles and not c.augmentation]
    if not clips:
        raise ValueError("the folder has no clips with joint rotations to label")
    pieces, owner = [], []
    for i, clip in enumerate(clips):
        angles = dataset.arrays["angles"][clip.start : clip.stop]
        for a, b in chunk_bounds(len(angles), MAX_FRAMES):
            pieces.append(angles[a:b])
            owner.append(i)
    unknown = [UNKNOWN] * len(pieces)
    sequences = SequenceSet.from_pieces(pieces, unknown, unknown, [clips[i].take for i in owner])
    probabilities = {kind: predict(classifiers[kind], sequences) for kind in KINDS}
    owner, lengths = np.asarray(owner), sequences.lengths
    rows = []
    for i, clip in enumerate(clips):
        mine = owner == i
        row = {"clip": clip.name, "content": clip.content or "", "style": clip.style or ""}
        for kind in KINDS:
            p = np.average(probabilities[kind][mine], axis=0, weights=lengths[mine])
            best = int(p.argmax())
            row[f"predicted_{kind}"] = classifiers.vocabularies[kind].names[best]
            row[f"{kind}_probability"] = round(float(p[best]), 4)
        rows.append(row)
    return rows
