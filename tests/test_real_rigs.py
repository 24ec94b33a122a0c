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
import torch

from generation.cli import main
from generation.motion.bvh import load_motion, read_bvh, write_bvh
from generation.motion.dataset import DatasetOptions, build_dataset, load_body_motion
from generation.motion.features import angle_feature_spec, encode_angles
from generation.motion.npz import load_motion_npz
from generation.motion.takes import natural_takes
from generation.motion.units import skeleton_size
from measures.units import UNITS
from tests.test_any_rig import figure_box

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


# Each rig's file, its unit (as the command line names it and as --scale does), what info says of its
# frames, and the body's foot-to-head length (``units.skeleton_size``) in cm.
RIG_FILES = {"cmu": (CMU, "CMU units (x5.64444 to cm)", "cmu", "510 frames at 120 fps (4.25 s), 31 joints", 161.5),
             "cmu-metres": (CMU_METRES, "metres (x100 to cm)", "m", "510 frames at 120 fps (4.25 s), 31 joints", 161.5),
             "accad": (ACCAD, "centimetres", "cm", "581 frames at 120 fps (4.84 s), 22 joints", 155.2)}
# The smallest MoGlow the cpu preset shrinks to: a few steps of training take seconds.
TINY = ["--preset", "cpu", "--set", "steps=2", "--set", "tau=3", "--set", "lstm_hidden=16", "--set", "batch_size=4"]


@pytest.fixture(scope="module")
def rig_folders(tmp_path_factory) -> dict[str, Path]:
    """Each rig's take three times over (a, b, c): three takes, so the seeded split has one
    to hold out, one for validation and one to train on, as a lab's folder would."""
    folders = {}
    for name, (source, *_) in RIG_FILES.items():
        folder = folders[name] = tmp_path_factory.mktemp(name)
        for take in "abc":
            shutil.copy(source, folder / f"{take}.bvh")
    return folders


@pytest.mark.parametrize("rig", sorted(RIG_FILES))
def test_every_command_runs_on_a_real_rig_read_in_its_own_unit(rig, rig_folders, tmp_path, capsys):
    source, unit, scale, frames, size = RIG_FILES[rig]
    folder, cache = rig_folders[rig], str(tmp_path / "cache")
    said = f"motion units: {unit}, y up (unit detected from the skeleton's size"

    assert main(["info", str(source)]) == 0
    out = capsys.readouterr().out
    assert said in out and f"{source}: {frames}" in out

    video = tmp_path / "render" / f"{rig}.mp4"
    assert main(["render", str(source), "-o", str(video), "--size", "160x120", "--sheet"]) == 0
    assert said in capsys.readouterr().out and video.stat().st_size > 5_000 and video.with_suffix(".png").is_file()
    body = load_body_motion(source, 20.0, scale=UNITS[scale])
    assert skeleton_size(body.skeleton) == pytest.approx(size, abs=0.1)
    # Drawn at the size every rig is drawn at (foot to head, 48 % of the frame; a Bandai-Namco walker fills 43 %).
    assert 0.33 < figure_box(body)[1] / 240 < 0.5

    assert main(["build-dataset", str(folder), "--cache-dir", cache]) == 0
    out = capsys.readouterr().out
    assert said in out and "1 training takes" in out and "1 held-out test takes (1 windows)" in out

    natural = tmp_path / "NAT"
    assert main(["natural", str(folder), "--out", str(natural), "--seconds", "3"]) == 0
    (clip,) = natural.glob("*.npz")
    assert load_motion_npz(clip).positions.shape == (60, body.skeleton.n_joints, 3)
    assert main(["natural", str(folder), "--takes", "c", "--out", str(tmp_path / "named")]) == 0
    assert load_motion_npz(tmp_path / "named" / "c.npz").n_frames == 80

    checkpoint = tmp_path / "tiny.safetensors"
    assert main(["train", str(folder), "--out", str(checkpoint), "--steps", "2", "--eval-every", "2", "--threads", "1",
                 "--cache-dir", cache, *TINY]) == 0, capsys.readouterr().err
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        samples = tmp_path / "samples"
        assert main(["sample", str(checkpoint), "-c", "held-out", "walk-straight", "--data", str(folder), "--seconds",
                     "2", "--warmup-seconds", "0.5", "--threads", "1", "--out", str(samples)]) == 0
        assert torch.get_num_threads() == 1  # --threads as train has it
    finally:
        torch.set_num_threads(threads)
    assert "2 clips in" in capsys.readouterr().out
    held_out = next(samples.glob(f"{clip.stem}*_00.bvh"))
    assert load_motion(held_out).positions.shape == (40, body.skeleton.n_joints, 3)
    walk = load_motion(samples / "walk-straight_00.bvh")
    assert walk.n_frames == 80 and np.isfinite(walk.positions).all()
    assert walk.skeleton.names == body.skeleton.names


def test_the_cmu_take_in_cmu_units_and_in_metres_gives_the_same_datasets_and_natural_clips(rig_folders, tmp_path):
    """The metres file is the CMU-unit file rounded to six decimals of a metre: 0.002 cm."""
    datasets = [build_dataset(rig_folders[rig], DatasetOptions(), cache_dir=tmp_path, progress=False)
                for rig in ("cmu", "cmu-metres")]
    assert [d.options.scale for d in datasets] == [UNITS["cmu"], UNITS["m"]]
    for key in ("pose", "control", "angles"):
        np.testing.assert_allclose(datasets[0].arrays[key], datasets[1].arrays[key], atol=0.005, err_msg=key)
    takes = [natural_takes(rig_folders[rig], names=["a"])[0][0] for rig in ("cmu", "cmu-metres")]
    np.testing.assert_allclose(takes[0].motion.positions, takes[1].motion.positions, atol=0.005)
