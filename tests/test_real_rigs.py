"""Real motion capture of other rigs (``tests/fixtures/rigs``, each with its SOURCE.md):
a CMU take as the 3ds Max-friendly conversion writes it, in CMU units and in metres, and
an ACCAD walk on CMU's ASF names. Every command runs on them as a lab would run it, and
the two unit systems give the same motion."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from generation.cli import main
from generation.motion.bvh import read_bvh, write_bvh
from generation.motion.dataset import DatasetOptions, build_dataset, load_body_motion
from generation.motion.features import angle_feature_spec, encode_angles
from generation.motion.units import UNITS

RIGS = Path(__file__).parent / "fixtures" / "rigs"
CMU = RIGS / "cmu-3dsmax" / "131_01.bvh"
CMU_METRES = RIGS / "cmu-3dsmax-metres" / "scaled_131_01.bvh"
ACCAD = RIGS / "accad" / "Swagger.bvh"


def test_the_hips_look_up_the_spine_past_cmus_zero_offset_lowerback():
    """CMU's spine starts at ``lowerback`` with OFFSET 0 0 0: "up" is the first spine
    joint that stands apart, so an upright walker's hips neither pitch nor roll much."""
    for path, scale in ((CMU, UNITS["cmu"]), (ACCAD, UNITS["cm"])):
        motion = load_body_motion(path, 20.0, scale=scale)
        spec = angle_feature_spec(motion.skeleton)
        np.testing.assert_allclose(spec.alignment.T @ spec.alignment, np.eye(3), atol=1e-9)
        pitch_roll = np.degrees(np.abs(encode_angles(motion, spec).values[:, 4:6]))
        assert np.isfinite(pitch_roll).all() and (np.median(pitch_roll, axis=0) < 10).all(), path.name


def test_a_spine_that_never_stands_apart_from_the_hips_is_refused_naming_the_file(tmp_path):
    bvh = read_bvh(CMU)
    names = bvh.skeleton.names
    spine = [names.index(n) for n in ("lowerback", "Chest", "Chest2", "lowerneck", "Neck", "Head")]
    offsets = bvh.skeleton.offsets.copy()
    offsets[spine] = 0.0
    folder = tmp_path / "flat-spine"
    folder.mkdir()
    write_bvh(replace(bvh, skeleton=replace(bvh.skeleton, offsets=offsets)), folder / "flat.bvh")
    with pytest.raises(ValueError, match=r"flat\.bvh: cannot align the hips 'Hips': no joint of its spine "
                                         r"\(lowerback, Chest, Chest2, lowerneck, Neck, Head\) stands above it"):
        build_dataset(folder, DatasetOptions(scale=UNITS["cmu"], up="y"), cache_dir=tmp_path / "cache",
                      progress=False)
