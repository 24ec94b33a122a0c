"""A sampling task samples every control of one system in one batch of the model.

The checkpoints are tiny MoGlows and an ERD trained on real clips; the controls are the
held-out clips' paths and presets. Each clip's noise comes from its own seed, so a clip
sampled in a batch is the clip ``Generator.sample`` gives alone.
"""

from __future__ import annotations

import numpy as np
import pytest

from generation.control import AttributeControl, control_from_dict, held_out_paths, preset_path
from generation.generator import Generator
from generation.models.moglow import MoGlow
from generation.motion.npz import load_motion_npz
from studyapp.models import ControlSignal, Stimulus, Study
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.dispatch import queue_stimuli
from studyapp.stimuli.sources import sampled_path
from studyapp.tasks import sample_stimuli
from tests.test_study_researcher import (files, new_study, queue, researcher, site,  # noqa: F401 (fixtures)
                                         upload_checkpoint)

PRESETS = ["walk-circle", "stand-still", "walk-zigzag"]

# Positions in cm. Float32 sums in another order for a batch than for one clip; bfloat16,
# which "auto" picks on CPUs with bfloat16 units, rounds its products to 8 bits.
FLOAT32_CM = 1e-3
BFLOAT16_CM = 1.0


def sampling_study(client, researcher, files) -> Study:
    """A MoGlow with the held-out controls cut to 4 s and three 4 s presets: one length."""
    study = new_study(researcher)
    upload_checkpoint(client, study, files.good.read_bytes())
    client.post(f"/studies/{study.pk}/controls/", {"action": "held_out", "seconds": "4", "count": ""})
    client.post(f"/studies/{study.pk}/controls/", {"action": "presets", "presets": PRESETS})
    assert study.controls.count() == 2 + len(PRESETS)
    return study


def send_to_sampling(study: Study) -> list[Stimulus]:
    stimuli, _ = plan_stimuli(study)
    queue_stimuli(stimuli)
    return list(Stimulus.objects.filter(study=study).select_related("system", "control").order_by("pk"))


def run_sampling(stimuli: list[Stimulus]) -> dict:
    return sample_stimuli.apply(([(s.pk, s.task_id) for s in stimuli],)).get()


@pytest.fixture
def count_model_calls(monkeypatch) -> list[int]:
    """The batch size of every call of MoGlow's ``generate``."""
    calls: list[int] = []
    generate = MoGlow.generate

    def counted(self, control, *args, **kwargs):
        calls.append(len(control))
        return generate(self, control, *args, **kwargs)

    monkeypatch.setattr(MoGlow, "generate", counted)
    return calls


@pytest.mark.parametrize("precision, tolerance_cm", [("float32", FLOAT32_CM), ("auto", BFLOAT16_CM)])
def test_a_clip_sampled_in_a_batch_equals_the_clip_sampled_alone(files, motion_data, precision, tolerance_cm):
    from generation.motion.dataset import build_dataset
    from generation.motion.dataset_options import DatasetOptions

    generator = Generator.load(files.good)
    dataset = build_dataset(files.clips, DatasetOptions(), cache_dir=files.root / "var" / "cache", progress=False)
    controls = [*held_out_paths(dataset, 4.0), preset_path("walk-circle"), preset_path("walk-circle")]
    seeds = [3, 5, 0, 1]
    batch = generator.sample_batch(controls, seeds, precision=precision)
    alone = [generator.sample(c, n=1, seed=s, precision=precision)[0] for c, s in zip(controls, seeds)]
    for together, single in zip(batch, alone):
        assert together.positions.shape == single.positions.shape
        np.testing.assert_allclose(together.positions, single.positions, rtol=0, atol=tolerance_cm)
    # The two walk-circles differ only by their seeds, and so does their motion.
    assert np.abs(batch[2].positions - batch[3].positions).max() > 100 * tolerance_cm


def test_a_label_controlled_models_batch_equals_its_clips_sampled_alone(files):
    generator = Generator.load(files.erd)
    action, style = generator.model.actions[0], generator.model.styles[0]
    controls = [AttributeControl(action, style, 40, generator.fps), AttributeControl(action, style, 40, generator.fps),
                AttributeControl(action, style, 25, generator.fps)]
    seeds = [1, 2, 1]
    batch = generator.sample_batch(controls, seeds, precision="float32")
    for control, seed, together in zip(controls, seeds, batch):
        single = generator.sample(control, n=1, seed=seed, precision="float32")[0]
        np.testing.assert_allclose(together.positions, single.positions, rtol=0, atol=FLOAT32_CM)
    assert np.abs(batch[0].positions - batch[1].positions).max() > 100 * FLOAT32_CM


@pytest.mark.django_db
def test_a_sampling_task_calls_the_model_once_for_all_controls_of_its_system(client, researcher, site, files, queue,
                                                                            settings, count_model_calls):
    study = sampling_study(client, researcher, files)
    stimuli = send_to_sampling(study)
    assert run_sampling(stimuli)["sampled"] == len(stimuli) == 5
    assert count_model_calls == [5]

    generator = Generator.load(files.good)
    for stimulus in stimuli:
        alone = generator.sample(control_from_dict(stimulus.control.control), n=1, seed=stimulus.seed)[0]
        sampled = load_motion_npz(sampled_path(stimulus))
        np.testing.assert_allclose(sampled.positions, alone.positions, rtol=0, atol=BFLOAT16_CM)

    # Running the task again changes nothing: every clip is sampled already.
    before = {s.pk: sampled_path(s).read_bytes() for s in stimuli}
    count_model_calls.clear()
    assert run_sampling(stimuli)["sampled"] == 5 and count_model_calls == []
    assert {s.pk: sampled_path(s).read_bytes() for s in stimuli} == before


@pytest.mark.django_db
def test_a_system_with_more_controls_than_a_batch_is_sampled_in_batches_of_the_setting(
        client, researcher, site, files, queue, settings, count_model_calls):
    settings.STUDY_SAMPLE_BATCH = 2
    study = sampling_study(client, researcher, files)
    stimuli = send_to_sampling(study)
    assert run_sampling(stimuli)["sampled"] == 5
    assert count_model_calls == [2, 2, 1]
    assert all(sampled_path(s).is_file() for s in stimuli)


@pytest.mark.django_db
def test_a_control_the_model_cannot_follow_fails_alone_and_the_others_are_sampled(
        client, researcher, site, files, queue, settings, count_model_calls):
    study = sampling_study(client, researcher, files)
    at_30_fps = preset_path("walk-circle", fps=30.0).to_dict()
    ControlSignal.objects.create(study=study, name="thirty", origin=ControlSignal.Origin.SYNTHETIC,
                                 control={**at_30_fps, "name": "thirty"}, seconds=4.0)
    stimuli = send_to_sampling(study)
    result = run_sampling(stimuli)
    assert (result["sampled"], result["of"]) == (5, 6) and count_model_calls == [5]
    failed = Stimulus.objects.get(control__name="thirty")
    assert failed.status == "failed" and failed.error == (
        "ValueError: control is at 30 fps but the model was trained at 20 fps")
    assert not sampled_path(failed).exists()
    assert all(sampled_path(s).is_file() for s in stimuli if s.pk != failed.pk)


@pytest.mark.django_db
def test_a_missing_checkpoint_fails_every_clip_of_its_system_with_the_reason(client, researcher, site, files, queue,
                                                                            settings):
    study = sampling_study(client, researcher, files)
    stimuli = send_to_sampling(study)
    stimuli[0].system.checkpoint_path().unlink()
    assert run_sampling(stimuli)["sampled"] == 0
    errors = set(Stimulus.objects.filter(study=study).values_list("status", "error"))
    assert len(errors) == 1 and errors.pop()[1].startswith("FileNotFoundError: the checkpoint of MoGlow is missing")


@pytest.mark.parametrize("value", ["0", "2.5", "many"])
def test_a_sample_batch_that_is_not_a_whole_number_of_at_least_one_is_refused(tmp_path, value):
    from tests.test_settings import run_settings

    refused = run_settings(STUDYAPP_VAR_DIR=str(tmp_path), STUDY_SAMPLE_BATCH=value)
    message = {"0": "STUDY_SAMPLE_BATCH=0 is not a whole number of at least 1",
               "2.5": "STUDY_SAMPLE_BATCH=2.5 is not a whole number of at least 1",
               "many": "STUDY_SAMPLE_BATCH='many' is not a number"}[value]
    assert refused.returncode != 0 and message in refused.stderr
