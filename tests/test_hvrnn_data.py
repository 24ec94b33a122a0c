"""Attribute-labelled angle sequences: chunking, masks, labels and the two training halves."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from generation.hvrnn.data import FPS, MAX_FRAMES, ROOT_DIMS, Vocabulary, chunk_bounds, split_halves
from tests.hvrnn_setup import data  # noqa: F401  (a fixture)


def test_chunks_are_equal_pieces_of_at_most_the_limit():
    assert chunk_bounds(210, 200) == [(0, 105), (105, 210)]
    assert chunk_bounds(200, 200) == [(0, 200)]
    assert chunk_bounds(20, 200) == [(0, 20)]
    bounds = chunk_bounds(1901, 200)
    assert len(bounds) == 10 and bounds[0][0] == 0 and bounds[-1][1] == 1901
    assert all(b - a <= 200 for a, b in bounds)
    assert all(b == a2 for (_, b), (a2, _) in zip(bounds[:-1], bounds[1:]))


def test_unknown_label_is_refused_by_name():
    vocabulary = Vocabulary("style", ("happy", "sad"))
    assert vocabulary.index("sad") == 1
    with pytest.raises(ValueError, match="unknown style 'grumpy'; known styles: happy, sad"):
        vocabulary.index("grumpy")


def test_halves_are_balanced_disjoint_and_deterministic():
    takes = [(f"t{a}{s}", f"a{a}", f"s{s}") for a in range(4) for s in range(6)]
    first = split_halves(takes, seed=3)
    assert first == split_halves(list(reversed(takes)), seed=3)
    assert len(first) == 12
    per_action = Counter(a for t, a, _ in takes if t in first)
    per_style = Counter(s for t, _, s in takes if t in first)
    # Each action has 6 takes and each style 4: a half holds about half of each.
    assert all(abs(per_action[f"a{a}"] - 3) <= 1 for a in range(4))
    assert all(abs(per_style[f"s{s}"] - 2) <= 1 for s in range(6))
    assert split_halves(takes, seed=4) != first


def test_real_sequences_are_padded_masked_and_labelled(data):
    test = data.sequences("test")
    assert data.fps == FPS
    assert test.features.shape[1:] == (MAX_FRAMES, data.feature_dim)
    assert test.features.dtype == np.float32 and test.mask.dtype == bool
    # The mask is a prefix of real frames; padding is zero; real frames are finite.
    lengths = test.lengths
    assert (lengths >= 1).all() and (lengths <= MAX_FRAMES).all()
    assert (test.mask == (np.arange(MAX_FRAMES)[None] < lengths[:, None])).all()
    assert (test.features[~test.mask] == 0).all()
    assert np.isfinite(test.features).all()
    # Unstandardised quaternions have unit length on real frames.
    quats = test.features[test.mask][:, ROOT_DIMS:].reshape(-1, 4)
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-4)
    # Every sequence's labels are its clip's.
    clips = {c.take: c for c in data.clips("test")}
    for take, action, style in zip(test.takes, test.action, test.style):
        assert data.actions.names[action] == clips[take].content
        assert data.styles.names[style] == clips[take].style
    # All frames of the held-out clips are there, once.
    assert lengths.sum() == sum(c.stop - c.start for c in data.clips("test"))


def test_parts_are_disjoint_and_halves_cover_training(data):
    takes = {part: {c.take for c in data.clips(part)} for part in ("train", "classifier", "model", "test")}
    assert takes["classifier"] | takes["model"] == takes["train"]
    assert not takes["classifier"] & takes["model"]
    assert not takes["train"] & takes["test"]
    assert all(not c.augmentation and c.has_angles for c in data.clips("train"))
    # Both halves see every action and style with training clips of at least two takes.
    for kind, vocabulary in (("content", data.actions), ("style", data.styles)):
        train = Counter(getattr(c, kind) for c in data.clips("train"))
        for half in ("classifier", "model"):
            seen = {getattr(c, kind) for c in data.clips(half)}
            assert {name for name, n in train.items() if n >= 2} <= seen, (kind, half)
        assert set(vocabulary.names) == set(train)


def test_standardisers_scale_all_or_only_the_root(data):
    everything = data.sequences("train", data.standardizer("all"))
    real = everything.features[everything.mask]
    assert np.allclose(real.mean(axis=0), 0, atol=1e-2) and np.allclose(real.std(axis=0), 1, atol=1e-2)
    root_only = data.sequences("train", data.standardizer("root"))
    quats = root_only.features[root_only.mask][:, ROOT_DIMS:].reshape(-1, 4)
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-4)
    assert np.allclose(root_only.features[root_only.mask][:, :ROOT_DIMS], real[:, :ROOT_DIMS], atol=1e-5)
    with pytest.raises(ValueError, match="scope 'joints'"):
        data.standardizer("joints")
    with pytest.raises(ValueError, match="unknown part 'holdout'"):
        data.sequences("holdout")
