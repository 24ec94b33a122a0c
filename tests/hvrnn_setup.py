"""What the HVRNN tests share: the labelled angle data and a tiny classifier configuration."""

from __future__ import annotations

import pytest

from generation.hvrnn.classifiers import ClassifierConfig
from generation.hvrnn.data import AttributeData, load_attribute_data

# Trains both classifiers in seconds and still reaches 0.5 and more held-out accuracy.
TINY_CLASSIFIERS = ClassifierConfig(channels=(32, 32, 32), steps=150, batch_size=16, lr=3e-3)


@pytest.fixture(scope="module")
def data(motion_data, pytestconfig) -> AttributeData:
    """The real data as attribute sequences (imported as a fixture by the HVRNN test modules)."""
    # The cache is keyed by a fingerprint of files and options, so reusing it across runs is safe.
    return load_attribute_data(motion_data, cache_dir=pytestconfig.cache.mkdir("motion-dataset"), progress=False)
