"""The study's workers sample in the precision "auto" picks (Generator.sample's default)
and log which, once per loaded model."""

from __future__ import annotations

import logging
from pathlib import Path

CHECKPOINT = Path(__file__).resolve().parents[1] / "models" / "moglow-cpu.safetensors"


def test_a_worker_logs_the_precision_its_model_samples_in(caplog):
    from studyapp.stimuli import sources

    with caplog.at_level(logging.INFO, logger="studyapp.stimuli.sources"):
        generator = sources._generator(str(CHECKPOINT), "digest-of-this-test", "cpu")
    assert generator.resolve_precision() in ("bfloat16", "float32")
    assert f"{CHECKPOINT} samples in {generator.resolve_precision()} (precision auto)" in caplog.text
