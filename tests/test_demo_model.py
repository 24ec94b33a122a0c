"""`make demo` uses the committed MoGlow only if it learnt from the demo's data, prepared
the demo's way; otherwise it would spend an hour training its own."""

from __future__ import annotations

from generation.checkpoint import read_meta
from generation.motion.dataset import DatasetOptions, build_dataset, motion_folders
from studyapp.server import demo
from tests.test_checkpoint import clips_folder, dataset  # noqa: F401


def test_the_committed_moglow_learnt_from_the_demos_default_data_prepared_the_demos_way(motion_data, motion_data_2,
                                                                                      settings, tmp_path):
    assert {folder.resolve() for folder in motion_folders(settings.MOTION_DATA)} == {motion_data, motion_data_2}
    dataset = build_dataset(settings.MOTION_DATA, DatasetOptions(**demo.DATASET), cache_dir=tmp_path, progress=False)
    meta = read_meta(demo.COMMITTED_MODELS / "moglow-cpu.safetensors")
    assert meta.data_fingerprint == dataset.fingerprint
    assert DatasetOptions.from_dict(meta.features["dataset_options"]) == dataset.options


def test_a_committed_model_of_other_data_is_not_used(tmp_path):
    assert demo.committed_model("moglow", "0" * 64) is None
    assert demo.model_path(tmp_path, "moglow", 4000, "committed", "0" * 64) == tmp_path / "moglow-cpu-4000steps.safetensors"
    assert demo.model_path(tmp_path, "rnn", 400, "best", "0" * 64) == tmp_path / "rnn-cpu-400steps.best.safetensors"


def test_a_demo_model_whose_training_was_stopped_part_way_is_trained_on_not_used(dataset, tmp_path,  # noqa: F811
                                                                                 monkeypatch):
    from generation.train import TrainOptions, train

    monkeypatch.setattr(demo, "DEMO_MODELS", (("VAE", "vae", 4, "model", "best"),))
    models = tmp_path / "models"
    stopped = models / "vae-cpu-4steps.safetensors"
    train("vae", "cpu", dataset, stopped, TrainOptions(steps=2, eval_every=2), progress=False)  # as if Ctrl-C came then
    assert (models / "vae-cpu-4steps.best.safetensors").exists() and read_meta(stopped).step == 2

    checkpoints = demo.ensure_models(dataset, models)
    assert checkpoints["VAE"] == models / "vae-cpu-4steps.best.safetensors"
    assert read_meta(stopped).step == 4
    assert demo.ensure_models(dataset, models) == checkpoints and read_meta(stopped).step == 4  # done: left alone
