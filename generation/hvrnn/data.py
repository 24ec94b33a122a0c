"""Attribute-labelled angle sequences: what HVRNN, its classifiers and baselines learn from.

Choices, following Sec. 3.1 of Ghorbani et al.:

* 30 fps, angle features (six root values, then each joint's local quaternion), as
  ``generation.motion.dataset`` encodes them.
* Each clip is cut into the fewest sequences of at most 200 frames, of equal length
  (a 210-frame clip gives two of 105, not 200 + 10), padded with zeros to 200 frames
  and a boolean mask that is True on real frames.
* No mirroring: mirrored clips carry positions only (NaN angles), so they are skipped
  and building them would be wasted work.
* 20 % of the takes of each content are held out (``test``): at 10 % the held-out
  set has one take per content, too few sequences for a stable FID.
* The training takes are split once more, deterministically, into two halves balanced
  over actions and styles: ``classifier`` (the attribute classifiers train on it, as
  the paper trains them on half of the training data) and ``model`` (the other half).
  ``train`` is both halves.

Labels: the action is the dataset's *content*, the style its *style*; both
vocabularies are the labels of the training clips, sorted.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..motion.dataset import Clip, MotionDataset, Standardizer, build_dataset
from ..motion.dataset_options import DatasetOptions
from ..motion.features import ROOT_DIMS

FPS = 30.0
MAX_FRAMES = 200
HOLDOUT_FRACTION = 0.2
PARTS = ("train", "classifier", "model", "validation", "test")


def dataset_options(contents: tuple[str, ...] | None = None, seed: int = 0, **units: Any) -> DatasetOptions:
    """The dataset options of every attribute-controlled model (see the module docstring).
    ``units``: the files' ``scale``, ``up`` axis and rig (``root``, ``mirror_pairs``),
    as the command line's unit arguments give them; unit and up axis are detected unless given."""
    return DatasetOptions(fps=FPS, window_seconds=MAX_FRAMES / FPS, overlap=0.5, mirror=False, reverse=False,
                          contents=contents, holdout_fraction=HOLDOUT_FRACTION, seed=seed, **units)


@dataclass(frozen=True)
class Vocabulary:
    """The names of one kind of label ("action" or "style"), indexed 0..n-1."""

    kind: str
    names: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"unknown {self.kind} {name!r}; known {self.kind}s: {', '.join(self.names)}") from None


@dataclass(frozen=True)
class SequenceSet:
    """Padded sequences with their mask and labels, row for row."""

    features: np.ndarray  # (n, max_frames, dims) float32, zero where mask is False
    mask: np.ndarray  # (n, max_frames) bool, True on a prefix of real frames
    action: np.ndarray  # (n,) int64 indices into the action vocabulary
    style: np.ndarray  # (n,) int64 indices into the style vocabulary
    takes: tuple[str, ...]  # the take each sequence was cut from

    @classmethod
    def from_pieces(cls, pieces: list[np.ndarray], action: list[int], style: list[int], takes: list[str],
                    max_frames: int = MAX_FRAMES) -> "SequenceSet":
        """Sequences of at most ``max_frames`` frames each (frames, dims), zero-padded and masked."""
        features = np.zeros((len(pieces), max_frames, pieces[0].shape[-1]), dtype=np.float32)
        mask = np.zeros((len(pieces), max_frames), dtype=bool)
        for i, piece in enumerate(pieces):
            features[i, : len(piece)] = piece
            mask[i, : len(piece)] = True
        return cls(features, mask, np.asarray(action, dtype=np.int64), np.asarray(style, dtype=np.int64), tuple(takes))

    def __len__(self) -> int:
        return len(self.features)

    @property
    def lengths(self) -> np.ndarray:
        return self.mask.sum(axis=1)

    def subset(self, index: np.ndarray) -> "SequenceSet":
        index = np.asarray(index)
        return SequenceSet(self.features[index], self.mask[index], self.action[index], self.style[index],
                           tuple(np.asarray(self.takes, dtype=object)[index]))

    def tensors(self, device: str | torch.device = "cpu") -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(features, mask, action, style) as tensors on ``device``."""
        return (torch.as_tensor(self.features, device=device), torch.as_tensor(self.mask, device=device),
                torch.as_tensor(self.action, device=device), torch.as_tensor(self.style, device=device))


def split_halves(takes: list[tuple[str, str, str]], seed: int = 0) -> set[str]:
    """The ``classifier`` half of (take, action, style) triples; the rest is ``model``.

    Takes are visited in a seeded hash order and each goes to the half that so far
    holds fewer takes of its action plus its style (then fewer takes overall, then the
    classifier half), so both halves see every action and style about equally often.
    """
    order = sorted(set(takes), key=lambda t: hashlib.sha256(f"{seed}:{t[0]}".encode()).hexdigest())
    counts = [{}, {}]
    sizes = [0, 0]
    half_of = {}
    for take, action, style in order:
        score = [counts[h].get(("a", action), 0) + counts[h].get(("s", style), 0) for h in (0, 1)]
        h = min((0, 1), key=lambda h: (score[h], sizes[h], h))
        half_of[take] = h
        sizes[h] += 1
        for key in (("a", action), ("s", style)):
            counts[h][key] = counts[h].get(key, 0) + 1
    return {take for take, h in half_of.items() if h == 0}


def chunk_bounds(frames: int, max_frames: int) -> list[tuple[int, int]]:
    """(start, stop) of the fewest near-equal pieces of at most ``max_frames`` frames."""
    if max_frames < 1:
        raise ValueError(f"max_frames must be at least 1, got {max_frames}")
    n = max(1, math.ceil(frames / max_frames))
    edges = np.linspace(0, frames, n + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


@dataclass
class AttributeData:
    """A dataset seen as labelled angle sequences, with its vocabularies and halves."""

    dataset: MotionDataset
    actions: Vocabulary
    styles: Vocabulary
    classifier_takes: frozenset[str]

    @classmethod
    def from_dataset(cls, dataset: MotionDataset, seed: int = 0) -> "AttributeData":
        train = [c for c in dataset.select("train", augmented=False) if c.has_angles]
        if not train:
            raise ValueError("the dataset has no training clips with joint rotations; HVRNN needs angle features")
        for clip in dataset.clips:
            if clip.has_angles and (clip.content is None or clip.style is None):
                raise ValueError(f"clip {clip.name} has no {'content' if clip.content is None else 'style'} label; "
                                 "attribute-controlled models need a NAME.json with content and style beside each BVH")
        actions = Vocabulary("action", tuple(sorted({c.content for c in train})))
        styles = Vocabulary("style", tuple(sorted({c.style for c in train})))
        halves = split_halves([(c.take, c.content, c.style) for c in train], seed)
        return cls(dataset, actions, styles, frozenset(halves))

    @property
    def fps(self) -> float:
        return self.dataset.options.fps

    @property
    def feature_dim(self) -> int:
        return self.dataset.angle_spec.size

    def clips(self, part: str) -> list[Clip]:
        """The unaugmented clips with angles of one part: train (split into the classifier
        and model halves), validation or test."""
        if part not in PARTS:
            raise ValueError(f"unknown part {part!r}; use one of {PARTS}")
        split = part if part in ("validation", "test") else "train"
        clips = [c for c in self.dataset.select(split, augmented=False) if c.has_angles and self.knows(c)]
        if part == "classifier":
            return [c for c in clips if c.take in self.classifier_takes]
        if part == "model":
            return [c for c in clips if c.take not in self.classifier_takes]
        return clips

    def knows(self, clip: Clip) -> bool:
        """Whether the clip's action and style are among the training clips' labels. A
        held-out clip with a label no training clip has cannot be asked of a model, so
        the parts leave it out."""
        return clip.content in self.actions.names and clip.style in self.styles.names

    def standardizer(self, scope: str = "all") -> Standardizer:
        """The training clips' statistics: for every dimension (``all``), or for the six
        root values only (``root``), leaving quaternions as unit quaternions."""
        stats = self.dataset.stats["angles"]
        if scope == "all":
            return stats
        if scope == "root":
            mean, std = np.zeros_like(stats.mean), np.ones_like(stats.std)
            mean[:ROOT_DIMS], std[:ROOT_DIMS] = stats.mean[:ROOT_DIMS], stats.std[:ROOT_DIMS]
            return Standardizer(mean, std)
        raise ValueError(f"unknown standardisation scope {scope!r}; use 'all' or 'root'")

    def sequences(self, part: str, standardizer: Standardizer | None = None, max_frames: int = MAX_FRAMES) -> SequenceSet:
        """Every clip of ``part`` cut into padded sequences, standardised if asked."""
        clips = self.clips(part)
        if not clips:
            raise ValueError(f"the {part} part of the dataset has no clips with joint rotations and labels that "
                             "training clips have too (too few takes of each content?)")
        pieces, takes, actions, styles = [], [], [], []
        for clip in clips:
            angles = self.dataset.arrays["angles"][clip.start : clip.stop]
            if standardizer is not None:
                angles = standardizer.apply(angles)
            action, style = self.actions.index(clip.content), self.styles.index(clip.style)
            for a, b in chunk_bounds(len(angles), max_frames):
                pieces.append(angles[a:b])
                takes.append(clip.take)
                actions.append(action)
                styles.append(style)
        return SequenceSet.from_pieces(pieces, actions, styles, takes, max_frames)

    def quaternion_reference(self) -> np.ndarray:
        """Per joint, the sign-free average rotation of the training frames (joints, 4).

        q and −q are one rotation, and clips (and generated sequences) disagree on the
        sign; flipping each quaternion into the hemisphere of this reference gives a
        network one sign per rotation. It is the principal eigenvector of Σ q qᵀ
        (Markley's quaternion average), so it is itself free of the signs.
        """
        frames = np.concatenate([self.dataset.arrays["angles"][c.start : c.stop] for c in self.clips("train")])
        quats = frames[:, ROOT_DIMS:].reshape(len(frames), -1, 4).astype(np.float64)
        scatter = np.einsum("tja,tjb->jab", quats, quats)
        return np.linalg.eigh(scatter)[1][..., -1].astype(np.float32)


def load_attribute_data(folder: str | os.PathLike, contents: tuple[str, ...] | None = None,
                        cache_dir: str | os.PathLike | None = None, progress: bool = True, seed: int = 0,
                        **units: Any) -> AttributeData:
    """Build (or reuse from the cache) the angle dataset of a BVH folder with labels
    (``units`` as in ``dataset_options``)."""
    dataset = build_dataset(folder, dataset_options(contents, seed, **units), cache_dir=cache_dir, progress=progress)
    return AttributeData.from_dataset(dataset, seed)
