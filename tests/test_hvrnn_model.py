"""HVRNN: it learns from the real angle sequences, its schedules and ablations do what
they say, its samples are valid rotations, reproducible under a seed and survive a
checkpoint round trip, and unknown labels are refused by name."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from generation import registry
from generation.checkpoints.checkpoint import load_checkpoint
from generation.control import AttributeControl, preset_path
from generation.generator import Generator
from generation.hvrnn.classifiers import AttributeClassifier, ClassifierConfig
from generation.hvrnn.data import load_attribute_data
from generation.models.hvrnn import HVRNN
from generation.models.parts.layers import random_crop
from generation.registry import preset
from generation.train import TrainOptions, load_loss_classifiers, train


@pytest.fixture(scope="module")
def data(motion_data, pytestconfig):
    return load_attribute_data(motion_data, cache_dir=pytestconfig.cache.mkdir("motion-dataset"), progress=False)


def tiny(data, **changes):
    """A configuration that trains in seconds; no classifier loss unless asked."""
    config = dataclasses.replace(
        preset("hvrnn", "cpu"), word_dim=16, word_hidden=32, latent_dim=8, feature_dim=16, mlp_hidden=32, state_dim=32,
        kl_warmup=0, kl_anneal=1, classifier_weight=0.0, actions=data.actions.names,
        styles=data.styles.names)
    return dataclasses.replace(config, **changes)


def build(data, **changes) -> HVRNN:
    torch.manual_seed(0)
    model = HVRNN(tiny(data, **changes), data.feature_dim, len(data.actions) + len(data.styles))
    model.prepare(data)
    return model


def batches(data, frames: int = 60):
    features, mask, action, style = data.sequences("train", data.standardizer("root"), max_frames=frames).tensors()
    return {"pose": features, "mask": mask, "action": action, "style": style}


@pytest.mark.parametrize("output", ["quaternion", "axis_angle"])
def test_loss_falls_on_real_data(data, output):
    torch.set_num_threads(1)
    model = build(data, rotation_output=output)
    batch = batches(data)
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    generator = torch.Generator().manual_seed(0)
    losses = []
    for _ in range(60):
        index = torch.randint(len(batch["pose"]), (16,), generator=generator)
        loss, metrics = model.loss(**{k: v[index] for k, v in batch.items()})
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 0.1)
        optimizer.step()
        losses.append(metrics["reconstruction"])
    assert np.mean(losses[-10:]) < 0.5 * np.mean(losses[:10]), losses
    assert int(model.step) == 60


def test_random_crops_stay_within_the_real_frames():
    frames = torch.arange(10.0)[None, :, None].expand(3, 10, 2).contiguous()
    mask = torch.arange(10)[None] < torch.tensor([[10], [6], [3]])
    torch.manual_seed(0)
    for _ in range(20):
        pose, cut = random_crop(frames, mask, 4)
        assert pose.shape == (3, 4, 2) and cut[0].all() and cut[1].all()
        assert (pose[:, 1:, 0] - pose[:, :-1, 0] == 1).all()  # consecutive frames
        assert pose[1, -1, 0] <= 5 and pose[2, 0, 0] == 0 and cut[2].tolist() == [True, True, True, False]


def test_alpha_follows_the_skeleton_and_is_one_everywhere_for_NL(data):
    full, flat = build(data), build(data, hierarchical=False)
    names = [data.dataset.skeleton.names[j] for j in data.dataset.angle_spec.joints]
    alpha = dict(zip(names, full.alpha.tolist()))
    assert abs(np.mean(list(alpha.values())) - 1.0) < 1e-6
    # The spine drives the head and both arms; a toe drives only itself.
    assert alpha["Spine"] > alpha["UpperArm_L"] > alpha["Hand_L"] and alpha["UpperLeg_R"] > alpha["Toes_R"]
    assert torch.equal(flat.alpha, torch.ones_like(flat.alpha))


def test_ablation_presets_change_only_their_part():
    base = preset("hvrnn", "cpu")
    assert dataclasses.replace(base, word_codec=False) == preset("hvrnn", "cpu-SL")
    assert dataclasses.replace(base, hierarchical=False) == preset("hvrnn", "cpu-NL")
    assert dataclasses.replace(base, classifier_weight=0.0) == preset("hvrnn", "cpu-NC")
    assert preset("hvrnn", "paper").state_dim == 512 and preset("hvrnn", "paper").word_dim == 96
    with pytest.raises(ValueError, match="unknown HVRNN ablation 'XX'"):
        preset("hvrnn", "cpu-XX")
    with pytest.raises(ValueError, match="unknown HVRNN preset 'big'"):
        preset("hvrnn", "big")


def test_without_the_word_codec_words_are_the_poses(data):
    model = build(data, word_codec=False)
    assert not hasattr(model, "word_encoder")
    loss, metrics = model.loss(**{k: v[:4] for k, v in batches(data).items()})
    assert torch.isfinite(loss) and "word" not in metrics


def test_schedules_warm_up_anneal_and_cool_down(data):
    model = build(data, kl_warmup=10, kl_anneal=20)
    assert model.kl_weight(0) == model.kl_weight(9) == 0.0
    assert model.kl_weight(10) == pytest.approx(1 / 20) and model.kl_weight(19) == pytest.approx(0.5)
    assert model.kl_weight(29) == model.kl_weight(10_000) == 1.0
    model.config.classifier_weight, model.config.classifier_start, model.config.classifier_ramp = 0.5, 5, 10
    assert model.classifier_loss_weight(4) == 0.0 and model.classifier_loss_weight(9) == pytest.approx(0.25)
    assert model.classifier_loss_weight(100) == 0.5
    assert model.word_drop_probability(0) == 0.0 and model.word_drop_probability(10**6) == model.config.word_drop


def test_the_classifier_loss_enters_with_its_weight_and_reaches_the_model(data):
    model = build(data, classifier_start=0, classifier_ramp=1)
    model.config.classifier_weight = 1.0  # the classifiers come from use_classifiers, not from a file
    config = ClassifierConfig(channels=(8, 8, 8))
    torch.manual_seed(1)
    model.use_classifiers((AttributeClassifier(config, data.feature_dim, len(data.actions)),
                           AttributeClassifier(config, data.feature_dim, len(data.styles))))
    batch = {k: v[:4] for k, v in batches(data).items()}
    loss, metrics = model.loss(**batch)
    assert metrics["classifier_weight"] == 1.0 and metrics["classifier"] > 0
    loss.backward()
    assert model.decoder[0].weight.grad.abs().sum() > 0
    assert all(p.grad is None for c in model.classifiers for p in c.parameters())  # the classifiers stay frozen


def test_the_initial_state_keeps_its_spread_through_a_kl_term(data):
    batch = {k: v[:4] for k, v in batches(data).items()}
    losses = {}
    for weight in (0.0, 1.0):
        model = build(data, initial_kl_weight=weight).eval()  # eval: no schedules, so the terms are comparable
        torch.manual_seed(3)
        losses[weight], metrics = model.loss(**batch)
    # The same draws either way; the difference is the KL of the four sequences' Gaussians.
    assert (losses[1.0] - losses[0.0]).item() == pytest.approx(metrics["initial_kl"], rel=1e-4)
    model.train()
    model.initial.logvar.grad = None
    model.loss(**batch)[0].backward()
    assert model.initial.logvar.grad.abs().sum() > 0  # the spread is learned, and pulled towards 1


def test_fed_back_words_are_re_encoded_with_the_signs_of_real_words(data):
    for codec in (True, False):
        model = build(data, word_codec=codec)
        word_hat = torch.randn(5, model.decoder[-1].out_features)
        fed = model.fed_back(word_hat)
        frames = model.align(model.normalise(model.decode_word(word_hat))[0]).flatten(-2)
        assert torch.allclose(fed, model.encode_word(frames))
        if not codec:  # the raw poses: every quaternion on its reference's side, as real inputs are
            quats = fed.unflatten(-1, (model.config.word_length, -1))[..., 6:].unflatten(-1, (model.joints, 4))
            assert ((quats * model.reference).sum(-1) >= 0).all()


def test_classifier_loss_needs_the_classifiers_file(data):
    with pytest.raises(ValueError, match="needs the attribute classifiers' file"):
        load_loss_classifiers(build(data, classifier_weight=0.1), "")


@pytest.mark.parametrize("output", ["quaternion", "matrix", "axis_angle"])
def test_generated_rotations_are_unit_quaternions(data, output):
    model = build(data, rotation_output=output).eval()
    action, style = torch.tensor([0, 3]), torch.tensor([1, 2])
    features = model.generate(action, style, 50, generator=torch.Generator().manual_seed(0))
    assert features.shape == (2, 50, data.feature_dim)
    norms = features[..., 6:].unflatten(-1, (-1, 4)).norm(dim=-1)
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-5)


@pytest.fixture(scope="module")
def checkpoint(data, tmp_path_factory):
    patch = pytest.MonkeyPatch()
    small = {k: v for k, v in dataclasses.asdict(tiny(data)).items() if k not in ("actions", "styles")}
    patch.setitem(registry.MODELS["hvrnn"].presets, "tiny", registry.Preset(small, {"batch_size": 8}))
    path = tmp_path_factory.mktemp("hvrnn") / "hvrnn.safetensors"
    train("hvrnn", "tiny", data, path, TrainOptions(steps=4, eval_every=2), progress=False)
    yield path
    patch.undo()


def test_checkpoint_round_trip_gives_identical_samples(checkpoint, data):
    control = AttributeControl("walk", "happy", 45, data.fps)
    first = Generator.load(checkpoint).sample(control, n=2, seed=7)
    again = Generator.load(checkpoint).sample(control, n=2, seed=7)
    other = Generator.load(checkpoint).sample(control, n=2, seed=8)
    assert len(first) == 2 and first[0].positions.shape == (45, data.dataset.skeleton.n_joints, 3)
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a.positions, b.positions)
    assert not np.allclose(first[0].positions, other[0].positions)
    assert not np.allclose(first[0].positions, first[1].positions)  # n samples differ from each other
    model, meta = load_checkpoint(checkpoint)
    assert meta.kind == "hvrnn" and meta.step == 4 and meta.features["type"] == "angles"
    assert list(model.actions) == list(data.actions.names)
    assert torch.equal(model.alpha, build(data).alpha)


def test_unknown_labels_and_path_control_are_refused_by_name(checkpoint, data):
    generator = Generator.load(checkpoint)
    with pytest.raises(ValueError, match="unknown action 'jump'; this model knows the actions bow"):
        generator.sample(AttributeControl("jump", "happy", 30, data.fps))
    with pytest.raises(ValueError, match="unknown style 'sleepy'"):
        generator.sample(AttributeControl("walk", "sleepy", 30, data.fps))
    with pytest.raises(ValueError, match="controlled by action and style labels"):
        generator.sample(preset_path("walk-straight", data.fps))
    with pytest.raises(ValueError, match="trained at 30 fps"):
        generator.sample(AttributeControl("walk", "happy", 30, 20.0))


def test_train_command_chooses_the_rotation_output(motion_data, pytestconfig, tmp_path, capsys):
    from generation.checkpoints.checkpoint import read_meta
    from generation.cli import main

    cache = str(pytestconfig.cache.mkdir("motion-dataset"))
    common = [str(motion_data), "--cache-dir", cache, "--steps", "1", "--eval-every", "1", "--threads", "1",
              "--preset", "cpu-NC"]  # NC: no classifier loss, so no classifiers' file
    out = tmp_path / "hvrnn.safetensors"
    assert main(["train", *common, "--model", "hvrnn", "--rotation-output", "axis_angle", "--out", str(out)]) == 0
    assert read_meta(out).hyperparameters["rotation_output"] == "axis_angle"
    capsys.readouterr()
    assert main(["train", *common, "--model", "hvrnn", "--rotation-output", "euler",
                 "--out", str(tmp_path / "bad.safetensors")]) == 2
    assert "rotation_output must be one of" in capsys.readouterr().err
    assert main(["train", *common, "--model", "rnn", "--rotation-output", "matrix",
                 "--out", str(tmp_path / "rnn.safetensors")]) == 2
    assert "--rotation-output is for HVRNN" in capsys.readouterr().err
    assert not (tmp_path / "bad.safetensors").exists() and not (tmp_path / "rnn.safetensors").exists()
