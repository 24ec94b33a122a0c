"""HVRNN's evaluation: IS and FID from the attribute classifiers, t-SNE, and the two commands."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from analysis import cli as analysis_cli
from analysis.reports.attribute_scores import read_classifier_outputs, score_table
from analysis.motion.scores import frechet_distance, inception_score
from analysis.motion.tsne import conditional_affinities, kl_divergence, tsne
from generation import cli as generation_cli
from generation.hvrnn.classifiers import train_classifiers
from generation.hvrnn.data import ROOT_DIMS
from generation.hvrnn.evaluate import classifier_outputs
from generation.train import TrainOptions, train
from tests.hvrnn_setup import TINY_CLASSIFIERS as TINY, data  # noqa: F401  (data: a fixture)


@pytest.fixture(scope="module")
def classifiers(data):
    torch.set_num_threads(1)
    return train_classifiers(data, TINY, seed=0)[0]


def noise_like(data, sequences, seed=0):
    """Random sequences: root values from the data's mean and spread, uniformly random rotations."""
    rng = np.random.default_rng(seed)
    stats = data.standardizer("all")
    n, frames, dims = sequences.features.shape
    root = stats.mean[:ROOT_DIMS] + stats.std[:ROOT_DIMS] * rng.normal(size=(n, frames, ROOT_DIMS))
    quats = rng.normal(size=(n, frames, (dims - ROOT_DIMS) // 4, 4))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    features = np.concatenate([root, quats.reshape(n, frames, -1)], -1) * sequences.mask[..., None]
    return dataclasses.replace(sequences, features=features.astype(np.float32))


def test_fid_of_real_against_disjoint_real_is_far_below_real_against_noise(data, classifiers):
    test = data.sequences("test")
    reference = classifier_outputs(classifiers, test)
    real = classifier_outputs(classifiers, data.sequences("model"))
    noise = classifier_outputs(classifiers, noise_like(data, test))
    for kind in ("action", "style"):
        key = f"{kind}_activations"
        assert reference[key].shape == (len(test), TINY.channels[-1])
        between_real = frechet_distance(reference[key], real[key])
        against_noise = frechet_distance(reference[key], noise[key])
        assert between_real < 0.2 * against_noise, (kind, between_real, against_noise)


def test_inception_score_lies_between_one_and_the_number_of_classes(data, classifiers):
    outputs = classifier_outputs(classifiers, data.sequences("test"))
    for kind, classes in (("action", len(data.actions)), ("style", len(data.styles))):
        p = outputs[f"{kind}_probabilities"]
        assert np.allclose(p.sum(1), 1, atol=1e-5)
        score = inception_score(p)
        assert 1.0 <= score <= classes
        # Confident, varied predictions on real data: well above a uniform classifier's 1.
        assert score > 2.0, (kind, score)


def test_tsne_matches_its_perplexity_and_keeps_clusters_apart():
    rng = np.random.default_rng(0)
    labels = np.repeat(np.arange(3), 30)
    x = rng.normal(size=(3, 20))[labels] * 4 + rng.normal(size=(90, 20))
    p = conditional_affinities(x, perplexity=10)
    entropy = -np.where(p > 0, p * np.log(np.where(p > 0, p, 1)), 0).sum(1)
    assert np.allclose(entropy, np.log(10), atol=1e-4)
    y = tsne(x, perplexity=10, iterations=400)
    distances = np.square(y[:, None] - y[None]).sum(-1)
    np.fill_diagonal(distances, np.inf)
    assert (labels[distances.argmin(1)] == labels).all()
    joint = np.maximum((p + p.T) / 180, 1e-12)
    assert kl_divergence(joint, y) < 0.5 * kl_divergence(joint, rng.normal(size=(90, 2)))


def test_commands_write_scores_and_figures_for_a_trained_model(data, classifiers, motion_data, pytestconfig, tmp_path, capsys):
    torch.set_num_threads(1)
    erd = tmp_path / "erd.safetensors"
    train("erd", "cpu", data, erd, TrainOptions(steps=5, eval_every=5), progress=False,
          overrides={"encoder": (16,), "hidden": 16, "decoder": (16,), "batch_size": 4})
    classifiers_path = classifiers.save(tmp_path / "classifiers.safetensors", data.dataset.fingerprint, {})
    outputs = tmp_path / "outputs.npz"
    cache = str(pytestconfig.cache.mkdir("motion-dataset"))
    assert generation_cli.main(["hvrnn-eval", str(motion_data), "--cache-dir", cache, "--classifiers",
                                str(classifiers_path), "--checkpoint", f"erd={erd}", "--out", str(outputs)]) == 0
    read = read_classifier_outputs(outputs)
    assert list(read.sets) == ["test", "real", "erd"] and read.reference == "test"
    assert len(read.sets["erd"]["action"]) == len(read.sets["test"]["action"])
    table = score_table(read)
    assert np.isnan(table.loc[0, "FID action"]) and (table.loc[1:, ["FID action", "FID style"]] >= 0).all().all()
    assert analysis_cli.main(["hvrnn-scores", str(outputs), "--out", str(tmp_path / "scores")]) == 0
    assert "| erd |" in capsys.readouterr().out
    assert (tmp_path / "scores" / "figures" / "tsne_action.png").is_file()
    assert (tmp_path / "scores" / "tables" / "table2_is_fid.csv").is_file()
    assert generation_cli.main(["hvrnn-eval", str(motion_data), "--cache-dir", cache, "--classifiers",
                                str(classifiers_path), "--checkpoint", f"real={erd}", "--out", str(outputs)]) == 2
    # A path-controlled model is refused by name, not with a traceback.
    moglow = tmp_path / "moglow.safetensors"
    train("moglow", "cpu", data.dataset, moglow, TrainOptions(steps=1, eval_every=1), progress=False,
          overrides={"steps": 1, "tau": 1, "lstm_hidden": 4, "lstm_layers": 1, "batch_size": 2})
    capsys.readouterr()
    assert generation_cli.main(["hvrnn-eval", str(motion_data), "--cache-dir", cache, "--classifiers",
                                str(classifiers_path), "--checkpoint", f"flow={moglow}", "--out", str(outputs)]) == 2
    assert "a moglow model follows a path" in capsys.readouterr().err


def test_a_damaged_outputs_file_is_refused_by_name(tmp_path):
    path = tmp_path / "outputs.npz"
    np.savez(path, sets=np.array(["test"]), reference=np.array("test"), actions=np.array(["a"]), styles=np.array(["s"]))
    with pytest.raises(ValueError, match="set 'test' lacks action_probabilities"):
        read_classifier_outputs(path)
