"""The denoising autoencoder: it removes corruption from held-out real data, keeps shapes and rotations valid."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from generation.hvrnn.data import ROOT_DIMS
from generation.hvrnn.denoiser import Denoiser, DenoiserConfig, denoise_training_data, denoising_errors, train_denoiser
from tests.hvrnn_setup import data  # noqa: F401  (a fixture)

TINY = DenoiserConfig(channels=(176, 176), steps=120, batch_size=16, crop_frames=48)


@pytest.fixture(scope="module")
def trained(data):
    torch.set_num_threads(1)
    return train_denoiser(data, TINY, seed=0)


def test_identity_start_copies_its_input():
    denoiser = Denoiser(TINY, 86)
    x = torch.randn(2, 40, 86)
    assert torch.allclose(denoiser(x, torch.ones(2, 40, dtype=torch.bool)), x, atol=0.1)


def test_corruption_touches_the_configured_share_with_the_configured_noise():
    denoiser = Denoiser(TINY, 86)
    clean = torch.zeros(200, 100, 86)
    changed = denoiser.corrupt(clean, torch.Generator().manual_seed(0))
    touched = changed != 0
    assert abs(float(touched.float().mean()) - 0.1) < 0.005
    assert abs(float(changed[touched].std()) - 0.5) < 0.01


def test_denoised_held_out_data_is_closer_to_the_clean_data_than_its_corrupted_input(data, trained):
    denoiser, losses = trained
    errors = denoising_errors(denoiser, data.sequences("test"), seed=1)
    # 10 % of values with N(0, 0.5²) noise: the corrupted input's error is about 0.025.
    assert 0.02 < errors["corrupted"] < 0.03
    assert errors["denoised"] < 0.98 * errors["corrupted"], errors
    assert np.mean(losses[-20:]) < np.mean(losses[:20])


def test_applying_keeps_labels_padding_and_unit_quaternions(data, trained, tmp_path):
    denoiser, _ = trained
    test = data.sequences("test").subset(np.arange(5))
    clean = denoiser.apply(test)
    assert clean.features.shape == test.features.shape and clean.takes == test.takes
    assert (clean.features[~test.mask] == 0).all()
    quats = clean.features[test.mask][:, ROOT_DIMS:].reshape(-1, 4)
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-5)
    # On clean data it changes less than the corruption it learnt to remove (about 0.025).
    with torch.no_grad():
        before, after = (denoiser.inputs(torch.as_tensor(x.features))[torch.as_tensor(test.mask)] for x in (test, clean))
    assert float(((after - before) ** 2).mean()) < 0.02
    loaded = Denoiser.load(denoiser.save(tmp_path / "denoiser.safetensors", data.dataset.fingerprint, {}))
    assert np.array_equal(loaded.apply(test).features, clean.features)


def test_denoised_training_data_changes_training_clips_only(data, trained):
    denoiser, _ = trained
    cleaned = denoise_training_data(data, denoiser)
    assert cleaned.dataset.fingerprint.startswith(data.dataset.fingerprint + "+denoised-")
    assert np.array_equal(cleaned.sequences("test").features, data.sequences("test").features)
    # "before" is read after the call: the original data must be left as it was.
    before, after = data.sequences("train"), cleaned.sequences("train")
    assert after.features.shape == before.features.shape and not np.array_equal(after.features, before.features)
    quats = after.features[after.mask][:, ROOT_DIMS:].reshape(-1, 4)
    assert np.allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-5)


def test_train_cleans_the_training_takes_with_a_denoiser_file(data, trained, motion_data, pytestconfig, tmp_path, capsys):
    from generation.checkpoints.checkpoint import read_meta
    from generation.cli import main

    denoiser, _ = trained
    path = denoiser.save(tmp_path / "denoiser.safetensors", data.dataset.fingerprint, {})
    out = tmp_path / "erd.safetensors"
    cache = str(pytestconfig.cache.mkdir("motion-dataset"))
    common = [str(motion_data), "--cache-dir", cache, "--steps", "1", "--eval-every", "1", "--threads", "1"]
    assert main(["train", *common, "--model", "erd", "--preset", "cpu", "--denoiser", str(path), "--out", str(out)]) == 0
    assert read_meta(out).data_fingerprint.startswith(data.dataset.fingerprint + "+denoised-")
    capsys.readouterr()
    assert main(["train", *common, "--model", "rnn", "--preset", "cpu", "--denoiser", str(path),
                 "--out", str(tmp_path / "rnn.safetensors")]) == 2
    assert "--denoiser is for attribute-controlled models" in capsys.readouterr().err
