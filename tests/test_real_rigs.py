"""Other labs' rigs and files (``tests/lab_rigs.py``): real walks on the rig of CMU's
3ds Max-friendly conversion, in CMU units and in metres, and on ACCAD's rig with CMU's
ASF names. Every command runs on them as a lab would run it, and the two unit systems
give the same motion."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from generation.cli import main
from generation.motion.bvh import load_motion, read_bvh, write_bvh
from generation.motion.clip_files import load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.features import angle_feature_spec, encode_angles
from generation.motion.npz import load_motion_npz
from generation.motion.resample import resample
from generation.motion.takes import natural_takes
from generation.motion.skeleton_units import skeleton_size
from measures.units import UNITS
from tests.lab_rigs import LAB_FPS, LAB_RIGS
from tests.test_any_rig import figure_box

TAKE = "take_01.bvh"  # each rig's first take, as the commands that read one file are given it


def test_the_lab_files_hold_the_real_walks_on_their_rigs_as_their_labs_write_them(lab_rigs, motion_data_2):
    """What ``tests/lab_rigs.py`` promises of each file: the walk's own positions (to the
    file's rounding), the rig's zero offsets where its lab has them, its line ends."""
    for name, rig in LAB_RIGS.items():
        path = lab_rigs[name] / TAKE
        source = motion_data_2 / "data" / f"dataset-2_walk_{rig.sources[0]}.bvh"
        walk = resample(read_bvh(source).to_motion(), LAB_FPS)
        motion = load_motion(path, UNITS[rig.unit])
        taken = [(j, walk.skeleton.index(s)) for j, (_, _, s) in enumerate(rig.joints) if isinstance(s, str)]
        new, old = map(list, zip(*taken))
        assert motion.n_frames == rig.frames and motion.fps == LAB_FPS
        # Angles written to 2 decimals of a degree (ACCAD) move a hand by up to 0.02 cm.
        np.testing.assert_allclose(motion.positions[:, new], walk.positions[:rig.frames, old], atol=0.03, err_msg=name)
        zero = {n for n, o in zip(motion.skeleton.names[1:], motion.skeleton.offsets[1:]) if not o.any()}
        children = [motion.skeleton.names[j] for j in np.nonzero(motion.skeleton.parents == 0)[0]]
        text = path.read_bytes()
        head, frames = text.split(b"MOTION")
        if name == "accad":
            assert zero == {"lowerback"} and motion.skeleton.names[0] == "root" and b"\r\n" in frames
            assert b"Frames:\t581" in frames and children[0] == "lowerback" and children[1:3] == ["rfemur", "lfemur"]
        else:
            assert zero == {"LHipJoint", "RHipJoint", "lowerback", "lowerneck", "lhand", "rhand", "LThumb", "RThumb"}
            assert motion.skeleton.n_joints == 31 and children == ["LHipJoint", "RHipJoint", "lowerback"]
            assert (b"\r\n" in head) == (name == "cmu") and b"\r\n" not in frames.split(b"\n", 1)[1]


def test_the_hips_look_up_the_spine_past_a_zero_offset_lowerback(lab_rigs):
    """CMU's and ACCAD's spines start at ``lowerback`` with OFFSET 0 0 0: "up" is the first
    spine joint that stands apart, so an upright walker's hips neither pitch nor roll much."""
    for rig, scale in (("cmu", UNITS["cmu"]), ("accad", UNITS["cm"])):
        motion = load_body_motion(lab_rigs[rig] / TAKE, 20.0, scale=scale)
        spec = angle_feature_spec(motion.skeleton)
        np.testing.assert_allclose(spec.alignment.T @ spec.alignment, np.eye(3), atol=1e-9)
        pitch_roll = np.degrees(np.abs(encode_angles(motion, spec).values[:, 4:6]))
        assert np.isfinite(pitch_roll).all() and (np.median(pitch_roll, axis=0) < 10).all(), rig


def test_a_spine_that_never_stands_apart_from_the_hips_is_refused_naming_the_file(lab_rigs, tmp_path):
    bvh = read_bvh(lab_rigs["cmu"] / TAKE)
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


# Each rig's unit (as the command line names it and as --scale does), what info says of its
# frames, and the body's foot-to-head length (``units.skeleton_size``) in cm.
RIG_FILES = {"cmu": ("CMU units (x5.64444 to cm)", "cmu", "510 frames at 120 fps (4.25 s), 31 joints", 156.2),
             "cmu-metres": ("metres (x100 to cm)", "m", "510 frames at 120 fps (4.25 s), 31 joints", 156.2),
             "accad": ("centimetres", "cm", "581 frames at 120 fps (4.84 s), 22 joints", 156.2)}
# The smallest MoGlow the cpu preset shrinks to: a few steps of training take seconds.
TINY = ["--preset", "cpu", "--set", "steps=2", "--set", "tau=3", "--set", "lstm_hidden=16", "--set", "batch_size=4"]


@pytest.mark.parametrize("rig", sorted(RIG_FILES))
def test_every_command_runs_on_a_real_rig_read_in_its_own_unit(rig, lab_rigs, tmp_path, capsys):
    unit, scale, frames, size = RIG_FILES[rig]
    folder, cache = lab_rigs[rig], str(tmp_path / "cache")
    source = folder / TAKE
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
    assert main(["natural", str(folder), "--takes", "take_03", "--out", str(tmp_path / "named")]) == 0
    assert load_motion_npz(tmp_path / "named" / "take_03.npz").n_frames == 80

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


def test_the_cmu_take_in_cmu_units_and_in_metres_gives_the_same_datasets_and_natural_clips(lab_rigs, tmp_path):
    """The metres file rescales the CMU-unit file's numbers, rounded to a millionth of a
    metre: they differ by 0.0001 cm."""
    datasets = [build_dataset(lab_rigs[rig], DatasetOptions(), cache_dir=tmp_path, progress=False)
                for rig in ("cmu", "cmu-metres")]
    assert [d.options.scale for d in datasets] == [UNITS["cmu"], UNITS["m"]]
    for key in ("pose", "control", "angles"):
        np.testing.assert_allclose(datasets[0].arrays[key], datasets[1].arrays[key], atol=0.005, err_msg=key)
    takes = [natural_takes(lab_rigs[rig], names=["take_01"])[0][0] for rig in ("cmu", "cmu-metres")]
    np.testing.assert_allclose(takes[0].motion.positions, takes[1].motion.positions, atol=0.005)
