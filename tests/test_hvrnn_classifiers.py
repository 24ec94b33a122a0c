"""Attribute classifiers: accuracy on held-out real data, invariances, crops, saving."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from generation.checkpoints.checkpoint import CheckpointError
from generation.hvrnn.classifiers import AttributeClassifiers, accuracy, random_crops, train_classifiers
from generation.hvrnn.data import ROOT_DIMS
from generation.hvrnn.networks import save_network
from tests.hvrnn_setup import TINY_CLASSIFIERS as TINY, data  # noqa: F401  (data: a fixture)


@pytest.fixture(scope="module")
def trained(data):
    torch.set_num_threads(1)
    return train_classifiers(data, TINY, seed=0)


def test_held_out_accuracy_is_well_above_chance(data, trained):
    classifiers, history = trained
    result = accuracy(classifiers, data.sequences("test"))
    chance = {"action": 1 / len(data.actions), "style": 1 / len(data.styles)}
    for kind in ("action", "style"):
        # Chance is 1/16 (actions: no clip is dance-long) and 1/15 (styles); a tiny network reaches 0.5 and more.
        assert result[kind] > 4 * chance[kind], (kind, result[kind])
        assert np.mean(history[kind][-20:]) < 0.5 * np.mean(history[kind][:20])


def test_output_ignores_padding_and_quaternion_signs(data, trained):
    classifiers, _ = trained
    net = classifiers["style"]
    test = data.sequences("test").subset(np.arange(4))
    features, mask, _, _ = test.tensors()
    logits, activations = net(features, mask)
    assert len(activations) == 3 and activations[0].shape[:2] == (4, TINY.channels[0])
    longer = torch.cat([features, torch.randn(4, 50, features.shape[-1])], 1)
    longer_mask = torch.cat([mask, torch.zeros(4, 50, dtype=torch.bool)], 1)
    assert torch.allclose(net(longer, longer_mask)[0], logits, atol=1e-5)
    flipped = features.clone()
    flipped[..., ROOT_DIMS:] *= -1
    assert torch.allclose(net(flipped, mask)[0], logits, atol=1e-5)
    assert net.embed(features, mask).shape == (4, TINY.channels[-1])


def test_random_crops_stay_inside_and_are_long_enough():
    lengths = torch.tensor([10, 45, 200, 120])
    mask = torch.arange(200)[None] < lengths[:, None]
    generator = torch.Generator().manual_seed(0)
    for _ in range(20):
        crop = random_crops(mask, 45, generator)
        assert not (crop & ~mask).any()
        kept = crop.sum(1)
        assert (kept >= lengths.clamp(max=45)).all() and (kept <= lengths).all()
        # One contiguous stretch per row.
        assert ((crop[:, 1:].int() - crop[:, :-1].int()) == 1).sum(1).le(1).all()


def test_saved_classifiers_load_identically_and_bad_files_are_refused(data, trained, tmp_path):
    classifiers, _ = trained
    path = classifiers.save(tmp_path / "classifiers.safetensors", data.dataset.fingerprint, {"accuracy": 1.0})
    loaded = AttributeClassifiers.load(path)
    test = data.sequences("test").subset(np.arange(6))
    features, mask, _, _ = test.tensors()
    for kind in ("action", "style"):
        assert torch.equal(loaded[kind](features, mask)[0], classifiers[kind](features, mask)[0])
    assert loaded.vocabularies["style"] == data.styles
    other = save_network(tmp_path / "other.safetensors", torch.nn.Linear(2, 2), "denoiser", {})
    with pytest.raises(CheckpointError, match="'denoiser' network, not a 'attribute-classifiers'"):
        AttributeClassifiers.load(other)
    damaged = tmp_path / "damaged.safetensors"
    damaged.write_bytes(path.read_bytes()[:-8] + b"\x00" * 8)
    with pytest.raises(CheckpointError, match="digest"):
        AttributeClassifiers.load(damaged)


def test_labelling_names_the_held_out_clips_well_above_chance_and_ignores_side_files(
        data, trained, motion_data, pytestconfig, tmp_path, capsys):
    import csv
    import shutil

    from generation.cli import main
    from generation.hvrnn.labelling import label_clips

    classifiers, _ = trained
    rows = {r["clip"]: r for r in label_clips(classifiers, data.dataset)}
    held_out = data.clips("test")
    for kind, label in (("action", "content"), ("style", "style")):
        right = np.mean([rows[c.name][f"predicted_{kind}"] == getattr(c, label) for c in held_out])
        assert right > 4 / len(classifiers.vocabularies[kind].names), (kind, right)
    # The same clips without their label files: labelled alike, with empty given labels.
    unlabelled = tmp_path / "unlabelled"
    unlabelled.mkdir()
    for clip in held_out[:3]:
        shutil.copy(Path(motion_data) / "data" / f"{clip.name}.bvh", unlabelled)
    path = classifiers.save(tmp_path / "classifiers.safetensors", data.dataset.fingerprint, {})
    out = tmp_path / "labels.csv"
    assert main(["hvrnn-label", str(unlabelled), "--classifiers", str(path), "--out", str(out),
                 "--cache-dir", str(tmp_path / "cache")]) == 0, capsys.readouterr().err
    assert "3 clips, 3 without labels" in capsys.readouterr().out
    with out.open() as f:
        written = list(csv.DictReader(f))
    assert [r["clip"] for r in written] == sorted(c.name for c in held_out[:3])
    for r in written:
        assert r["content"] == r["style"] == ""
        for key in ("predicted_action", "predicted_style"):
            assert r[key] == rows[r["clip"]][key]


def test_labelling_clips_in_metres_or_z_up_gives_what_the_originals_give_and_mixed_units_are_refused(
        data, trained, motion_data, tmp_path, capsys):
    import csv
    import shutil

    from generation.cli import main
    from tests.rig_variants import write_variants

    classifiers, _ = trained
    path = classifiers.save(tmp_path / "classifiers.safetensors", data.dataset.fingerprint, {})
    folders = {name: tmp_path / name for name in ("original", "metres", "z-up")}
    for folder in folders.values():
        folder.mkdir()
    for clip in data.clips("test")[:3]:
        source = Path(motion_data) / "data" / f"{clip.name}.bvh"
        shutil.copy(source, folders["original"])
        for name, written in write_variants(source, tmp_path / "rigs" / clip.name).items():
            if name in folders:
                written.rename(folders[name] / source.name)

    def labels(folder: Path, *extra: str) -> list[dict]:
        out = tmp_path / f"{folder.name}.csv"
        assert main(["hvrnn-label", str(folder), "--classifiers", str(path), "--out", str(out),
                     "--cache-dir", str(tmp_path / "cache"), *extra]) == 0, capsys.readouterr().err
        with out.open() as f:
            return list(csv.DictReader(f))

    original = labels(folders["original"])
    for name, said in (("metres", "motion units: metres (x100 to cm), y up (unit detected"),
                       ("z-up", "motion units: centimetres, z up (unit detected")):
        rows = labels(folders[name])
        assert said in capsys.readouterr().out
        assert [(r["clip"], r["predicted_action"], r["predicted_style"]) for r in rows] == \
            [(r["clip"], r["predicted_action"], r["predicted_style"]) for r in original], name
        for row, expected in zip(rows, original):
            for kind in ("action", "style"):
                assert float(row[f"{kind}_probability"]) == pytest.approx(float(expected[f"{kind}_probability"]), abs=2e-4)
    # Given, the unit and axis are used as they are, and said so.
    assert labels(folders["z-up"], "--scale", "cm", "--up", "z") == labels(folders["z-up"])
    assert "motion units: centimetres, z up (scale given; up axis given)" in capsys.readouterr().out
    assert labels(folders["metres"], "--scale", "m") == labels(folders["metres"])
    assert "motion units: metres (x100 to cm), y up (scale given; up axis detected" in capsys.readouterr().out

    shutil.copy(folders["metres"] / f"{data.clips('test')[0].name}.bvh", folders["original"] / "in-metres.bvh")
    assert main(["hvrnn-label", str(folders["original"]), "--classifiers", str(path), "--out",
                 str(tmp_path / "mixed.csv"), "--cache-dir", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err
    assert "the files mix units: 3 are in cm" in err and "not in-metres.bvh (1." in err and "units: m)" in err
    assert not (tmp_path / "mixed.csv").exists()
