"""Held-out control with a lead-in: sampling warms up on the take's own start, as the MoGlow
authors' code samples a test take, and NAT is cut to the same frames."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from generation.cli import main
from generation.control import PathControl
from generation.generator import Generator
from generation.motion.clip_files import load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.features import decode_positions
from generation.motion.npz import load_motion_npz
from tests.test_checkpoint import checkpoint, clips_folder, dataset, monkeypatch_module, tiny_preset  # noqa: F401


def test_a_lead_in_is_sampled_as_the_start_of_the_control_and_then_dropped(checkpoint, dataset):  # noqa: F811
    generator = Generator.load(checkpoint)
    take = dataset.clip_arrays(dataset.select("test")[0])["control"][:60].astype(np.float64)
    led = PathControl(take[20:], 20.0, lead_in=take[:20])
    (motion,) = generator.sample(led, seed=3, temperature=0.8, warmup_seconds=1.0, precision="float32")

    # The same thing by hand: the model on the whole take's control from the mean pose.
    control = torch.as_tensor(generator.control_stats.apply(generator.control_layout(take, 20.0))[None], dtype=torch.float32)
    poses = generator.model.generate(control, None, 0.8, torch.Generator().manual_seed(3), "float32")
    expected = decode_positions(generator.pose_stats.invert(poses[0, 20:].double().numpy()), take[20:], 20.0)
    np.testing.assert_allclose(motion.positions, expected, atol=1e-6)


def test_natural_and_held_out_samples_with_the_same_lead_in_cover_the_same_frames(checkpoint, clips_folder,  # noqa: F811
                                                                                 tmp_path, capsys):
    cache = str(tmp_path / "cache")
    assert main(["natural", str(clips_folder), "--out", str(tmp_path / "NAT"), "--seconds", "2", "--lead-in", "1"]) == 0
    assert main(["sample", str(checkpoint), "-c", "held-out", "--data", str(clips_folder), "--seconds", "2",
                 "--lead-in", "1", "--out", str(tmp_path / "MoGlow")]) == 0, capsys.readouterr().err
    natural = {p.stem: load_motion_npz(p) for p in (tmp_path / "NAT").glob("*.npz")}
    sampled = {p.stem.rsplit("_", 1)[0]: load_motion_npz(p) for p in (tmp_path / "MoGlow").glob("*.npz")}
    assert natural and natural.keys() == sampled.keys()
    for name, motion in natural.items():
        take = load_body_motion(clips_folder / f"{name}.bvh", 20.0)
        np.testing.assert_allclose(motion.positions, take.positions[20:60])  # the take from 1 s to 3 s
        assert sampled[name].n_frames == motion.n_frames
    options = DatasetOptions.from_dict(Generator.load(checkpoint).meta.features["dataset_options"])
    assert len(natural) == len(build_dataset(clips_folder, options, cache_dir=cache, progress=False).select("test"))


def test_a_lead_in_longer_than_every_take_is_refused_and_writes_nothing(checkpoint, clips_folder, tmp_path,  # noqa: F811
                                                                       capsys):
    assert main(["natural", str(clips_folder), "--out", str(tmp_path / "NAT"), "--lead-in", "500"]) == 2
    assert main(["sample", str(checkpoint), "-c", "held-out", "--data", str(clips_folder), "--lead-in", "500",
                 "--out", str(tmp_path / "MoGlow")]) == 2
    errors = capsys.readouterr().err
    assert "no test take is longer than the lead-in of 500 s" in errors
    assert "no held-out take is longer than the lead-in of 500 s" in errors
    assert not (tmp_path / "NAT").exists() and not (tmp_path / "MoGlow").exists()


def test_a_take_read_from_a_start_is_the_take_from_that_frame_and_a_start_past_its_end_names_the_file(clips_folder):  # noqa: F811
    path = next(clips_folder.glob("*.bvh"))
    take = load_body_motion(path, 20.0)
    np.testing.assert_array_equal(load_body_motion(path, 20.0, 2.0, start=1.0).positions, take.positions[20:60])
    np.testing.assert_array_equal(load_body_motion(path, 20.0, start=1.0).positions, take.positions[20:])
    with pytest.raises(ValueError, match=f"{path}: the take lasts {take.n_frames} frames at 20 fps"):
        load_body_motion(path, 20.0, start=take.n_frames / 20.0)


def test_held_out_samples_shorter_than_asked_are_warned_of_with_their_real_length(  # noqa: F811
        checkpoint, clips_folder, tmp_path, capsys):
    assert main(["sample", str(checkpoint), "-c", "held-out", "--data", str(clips_folder), "--seconds", "59",
                 "--lead-in", "1", "--out", str(tmp_path / "MoGlow")]) == 0
    errors = capsys.readouterr().err
    assert "s asked: its take ends sooner" in errors and "not the 59 s asked" in errors
