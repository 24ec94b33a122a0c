"""Checkpoints of the authors' MoGlow code, imported: they compute what the original computes.

The fixture (tests/fixtures/stylegestures) is data made with the authors' public code at
commit bd906cf (generation.stylegestures.SUPPORTED_COMMIT): a small locomotion model
(K=3, 16 hidden units, 10 past poses) trained for 30 steps on 12 real Bandai-Namco
clips put into their layout, its weights then perturbed so that no part is trivial;
the log-likelihood their code reports for two held-out clips, and the sample their
code draws for those clips' control under noise drawn as our MoGlow draws it. The
scaler is the one their locomotion loader fitted (with a numpy stand-in for sklearn's
StandardScaler: float64 mean and population standard deviation).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file

from generation.checkpoints.checkpoint import load_checkpoint, read_meta
from generation.cli import main
from generation.control import preset_path
from generation.generator import Generator
from generation.models.moglow import MoGlowConfig
from generation.motion.root import integrate
from generation.stylegestures import stylegestures_control

REPO = Path(__file__).resolve().parents[1]
FIXTURE = REPO / "tests" / "fixtures" / "stylegestures"
POSE_DIM = 63


@pytest.fixture(scope="module")
def reference() -> dict[str, torch.Tensor]:
    return load_file(FIXTURE / "reference.safetensors")


def their_checkpoint(folder: Path, graph: dict) -> Path:
    """The tensors saved as their trainer saves them: torch.save of its state dict."""
    path = folder / "trained.pkg"
    optim = {"state": {}, "param_groups": [{"lr": 1e-3, "betas": (0.9, 0.999), "eps": 1e-8, "weight_decay": 0,
                                            "amsgrad": False, "params": list(range(len(graph)))}]}
    torch.save({"global_step": 30, "graph": graph, "optim": optim, "criterion": {}}, path)
    return path


def their_data(folder: Path, train_clips: np.ndarray) -> Path:
    """Their training file: the clips, then the 100 their loader holds out for validation."""
    padding = np.zeros((100,) + train_clips.shape[1:], np.float32)
    np.savez(folder / "all_locomotion_train_20fps.npz", clips=np.concatenate([train_clips, padding]))
    return folder


@pytest.fixture(scope="module")
def imported(tmp_path_factory, reference) -> Path:
    folder = tmp_path_factory.mktemp("stylegestures")
    checkpoint = their_checkpoint(folder, load_file(FIXTURE / "graph.safetensors"))
    data = their_data(folder, reference["train_clips"].numpy())
    out = folder / "imported.safetensors"
    assert main(["import-stylegestures", str(checkpoint), "--hparams", str(FIXTURE / "hparams.json"),
                 "--data", str(data), "--out", str(out)]) == 0
    return out


def standardized_held_out(reference) -> torch.Tensor:
    """The held-out clips as their model sees them: standardised with their scaler."""
    clips = reference["held_out_clips"].double()
    return ((clips - reference["scaler_mean"]) / reference["scaler_scale"]).float()


def test_the_import_refits_their_standardisation_from_their_training_data(imported, reference):
    _, meta = load_checkpoint(imported)
    mean, scale = reference["scaler_mean"].numpy(), reference["scaler_scale"].numpy()
    np.testing.assert_allclose(meta.stats["pose"]["mean"], mean[:POSE_DIM], rtol=1e-12)
    np.testing.assert_allclose(meta.stats["pose"]["std"], scale[:POSE_DIM], rtol=1e-12)
    np.testing.assert_allclose(meta.stats["control"]["mean"], mean[POSE_DIM:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(meta.stats["control"]["std"], scale[POSE_DIM:], rtol=1e-12)
    assert meta.step == 30 and meta.hyperparameters["scale_offset"] == 2.0 and meta.hyperparameters["scale_floor"] == 1e-6


def test_the_imported_model_reports_their_log_likelihood(imported, reference):
    model, _ = load_checkpoint(imported)
    clips = standardized_held_out(reference)
    with torch.no_grad():
        log_likelihood = model.log_likelihood(clips[..., :POSE_DIM], clips[..., POSE_DIM:])
    # Theirs is the negative log-likelihood in bits per frame of each clip.
    nll_bits = -log_likelihood.sum(-1) / (math.log(2) * log_likelihood.shape[1])
    torch.testing.assert_close(nll_bits, reference["nll_bits_per_frame"], rtol=1e-5, atol=0)


def test_the_imported_model_draws_their_sample_from_the_same_noise(imported, reference):
    model, _ = load_checkpoint(imported)
    control = standardized_held_out(reference)[..., POSE_DIM:]
    noise = torch.randn(reference["sample_noise"].shape, generator=torch.Generator().manual_seed(7))
    assert torch.equal(noise, reference["sample_noise"])  # what generate draws from this seed
    sample = model.generate(control, None, 1.0, torch.Generator().manual_seed(7))
    torch.testing.assert_close(sample, reference["sample"], rtol=1e-5, atol=1e-5)


def test_the_imported_checkpoint_samples_and_renders_like_any_other(imported, tmp_path):
    motion = Generator.load(imported).sample(preset_path("walk-circle"), n=1, seed=3)[0]
    assert motion.positions.shape == (80, 21, 3) and np.isfinite(motion.positions).all()
    assert motion.skeleton.names[0] == "Hips" and motion.fps == 20.0
    out = tmp_path / "samples"
    assert main(["sample", str(imported), "-c", "walk-straight", "-o", str(out), "--render", "--size", "160x120"]) == 0
    assert (out / "walk-straight_00.mp4").stat().st_size > 1000


def test_their_control_layout_integrates_back_to_the_path():
    """Their decoder turns by minus the yaw change, then steps in the new root frame."""
    control = preset_path("walk-zigzag")
    theirs = stylegestures_control(control.velocities, control.fps)
    path = integrate(control.velocities, control.fps)
    xz, yaw = np.zeros(2), 0.0
    for i in range(len(theirs) - 1):
        np.testing.assert_allclose(xz, path.xz[i], atol=1e-9)
        assert yaw == pytest.approx(path.yaw[i], abs=1e-12)
        sideways, forward, minus_turn = theirs[i]
        yaw -= minus_turn
        # The root frame's +z is forward and +x its left; yaw turns +z towards +x.
        xz = xz + np.array([np.cos(yaw) * sideways + np.sin(yaw) * forward,
                            -np.sin(yaw) * sideways + np.cos(yaw) * forward])


class NotATensor:
    """Anything their checkpoint could hold that only unpickling rebuilds."""


def run_import(tmp_path: Path, checkpoint: Path, hparams: Path, reference, capsys) -> tuple[int, str, Path]:
    out = tmp_path / "imported.safetensors"
    data = their_data(tmp_path, reference["train_clips"].numpy())
    status = main(["import-stylegestures", str(checkpoint), "--hparams", str(hparams), "--data", str(data),
                   "--out", str(out)])
    return status, capsys.readouterr().err, out


def test_a_checkpoint_that_needs_unpickling_is_refused(tmp_path, reference, capsys):
    checkpoint = tmp_path / "pickled.pkg"
    torch.save({"global_step": 1, "graph": load_file(FIXTURE / "graph.safetensors"), "extra": NotATensor()}, checkpoint)
    status, err, out = run_import(tmp_path, checkpoint, FIXTURE / "hparams.json", reference, capsys)
    assert status == 2 and f"{checkpoint}: needs unpickling of objects" in err and "NotATensor" in err
    assert not out.exists()


def test_a_model_the_import_does_not_reproduce_is_refused_by_name(tmp_path, reference, capsys):
    hparams = json.loads((FIXTURE / "hparams.json").read_text())
    hparams["Glow"]["distribution"] = "studentT"
    path = tmp_path / "hparams.json"
    path.write_text(json.dumps(hparams))
    checkpoint = their_checkpoint(tmp_path, load_file(FIXTURE / "graph.safetensors"))
    status, err, out = run_import(tmp_path, checkpoint, path, reference, capsys)
    assert status == 2 and f'{path}: Glow.distribution is "studentT"' in err
    assert not out.exists()


def test_hparams_that_do_not_fit_the_tensors_name_the_tensor(tmp_path, reference, capsys):
    hparams = json.loads((FIXTURE / "hparams.json").read_text())
    hparams["Glow"]["hidden_channels"] = 32
    path = tmp_path / "hparams.json"
    path.write_text(json.dumps(hparams))
    checkpoint = their_checkpoint(tmp_path, load_file(FIXTURE / "graph.safetensors"))
    status, err, out = run_import(tmp_path, checkpoint, path, reference, capsys)
    assert status == 2 and "tensor flow.layers.0.f.lstm.weight_ih_l0 has shape (64, 694), the hparams need (128, 694)" in err
    assert not out.exists()


def test_checkpoints_saved_before_the_scale_options_load_as_before_and_keep_their_preset():
    from studyapp.stimuli.systems import preset_name

    meta = read_meta(REPO / "models" / "moglow-cpu.safetensors")
    older = {k: v for k, v in meta.hyperparameters.items() if k not in ("scale_offset", "scale_floor")}
    meta = dataclasses.replace(meta, hyperparameters=older)
    assert preset_name(meta) == "cpu"
    config = MoGlowConfig(**older)
    assert (config.scale_offset, config.scale_floor) == (0.0, 0.05)
