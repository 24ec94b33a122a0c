"""`make demo` uses the committed models (MoGlow, RNN, VAE and the BAD MoGlow) only where
each is the file its digest records and learnt from the demo's data, prepared the demo's
way; otherwise it stops, saying why, and trains its own only when asked (DEMO_TRAIN=1)."""

from __future__ import annotations

import hashlib
import shutil
from urllib.parse import parse_qs, urlparse

import pytest

from generation.checkpoint import read_meta
from generation.motion.clip_files import motion_folders
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from studyapp import demo
from tests.study_fixtures import make_study
from tests.test_checkpoint import clips_folder, dataset  # noqa: F401

pytestmark = pytest.mark.slow

# The state each committed model is (scripts/train-demo-models.sh).
TRAINED_STEPS = {"moglow-cpu.safetensors": 26_500, "rnn-cpu.safetensors": 400, "vae-cpu.safetensors": 1000,
                 "moglow-bad.safetensors": 15}


def test_every_committed_model_is_the_file_its_digest_records():
    digests = demo.recorded_digests()
    assert sorted(digests) == sorted(file for *_, file, _ in demo.DEMO_MODELS)
    for file, digest in digests.items():
        assert hashlib.sha256((demo.COMMITTED_MODELS / file).read_bytes()).hexdigest() == digest, file


def test_the_committed_models_learnt_from_the_demos_default_data_prepared_the_demos_way(motion_data, motion_data_2,
                                                                                       settings, demo_dataset_cache):
    assert {folder.resolve() for folder in motion_folders(settings.MOTION_DATA)} == {motion_data, motion_data_2}
    dataset = build_dataset(settings.MOTION_DATA, DatasetOptions(**demo.DATASET), cache_dir=demo_dataset_cache,
                            progress=False)
    for _, kind, _, file, _ in demo.DEMO_MODELS:
        meta = read_meta(demo.COMMITTED_MODELS / file)
        assert (meta.kind, meta.step, meta.data_fingerprint) == (kind, TRAINED_STEPS[file], dataset.fingerprint), file
        assert DatasetOptions.from_dict(meta.features["dataset_options"]) == dataset.options
        assert demo.committed_model(file, dataset.fingerprint) == (demo.COMMITTED_MODELS / file, "")


def test_a_committed_model_of_other_data_or_changed_is_not_used(tmp_path, monkeypatch):
    path, why = demo.committed_model("rnn-cpu.safetensors", "0" * 64)
    assert path is None and why == "models/rnn-cpu.safetensors learnt from other data (the locomotion of both " \
                                   "Bandai-Namco folders) than $MOTION_DATA holds"
    models = tmp_path / "models"
    shutil.copytree(demo.COMMITTED_MODELS, models)
    monkeypatch.setattr(demo, "COMMITTED_MODELS", models)
    monkeypatch.setattr(demo, "DIGESTS", models / "SHA256SUMS")
    monkeypatch.setattr(demo, "REPO", tmp_path)
    with (models / "vae-cpu.safetensors").open("r+b") as stream:
        stream.truncate(1000)  # a checkout cut short
    fingerprint = read_meta(demo.COMMITTED_MODELS / "rnn-cpu.safetensors").data_fingerprint
    assert demo.committed_model("vae-cpu.safetensors", fingerprint) == (
        None, "models/vae-cpu.safetensors is not the file whose digest models/SHA256SUMS records (git checkout models/)")
    (models / "rnn-cpu.safetensors").unlink()
    assert demo.committed_model("rnn-cpu.safetensors", fingerprint) == (None, "models/rnn-cpu.safetensors is missing")


def test_without_fitting_models_the_demo_stops_saying_why_and_trains_only_when_asked(dataset,  # noqa: F811
                                                                                     tmp_path, monkeypatch):
    from generation.train import TrainOptions, train

    monkeypatch.setattr(demo, "DEMO_MODELS", (("VAE", "vae", "model", "vae-cpu.safetensors", 4),))
    models = tmp_path / "models"
    with pytest.raises(demo.DemoStop, match="VAE: models/vae-cpu.safetensors learnt from other data .* DEMO_TRAIN=1"):
        demo.ensure_models(dataset, models)
    assert not models.exists()  # nothing trained unasked

    stopped = models / "vae-cpu-4steps.safetensors"
    train("vae", "cpu", dataset, stopped, TrainOptions(steps=2, eval_every=2), progress=False)  # as if Ctrl-C came then
    assert (models / "vae-cpu-4steps.best.safetensors").exists() and read_meta(stopped).step == 2
    checkpoints = demo.ensure_models(dataset, models, train_if_needed=True)
    assert checkpoints["VAE"] == models / "vae-cpu-4steps.best.safetensors"
    assert read_meta(stopped).step == 4
    assert demo.ensure_models(dataset, models) == checkpoints and read_meta(stopped).step == 4  # done: used, unasked


@pytest.mark.django_db
def test_each_printed_participant_link_carries_an_id_of_its_own():
    study = make_study(platform="link")
    links = [demo.participant_link("http://192.168.1.20:8000", study, "pid") for _ in range(3)]
    ids = [parse_qs(urlparse(link).query)["pid"][0] for link in links]
    assert len(set(ids)) == 3 and all(i.startswith("demo-") for i in ids)
    assert all(link.startswith(f"http://192.168.1.20:8000/p/{study.key}/?pid=") for link in links)
