"""The authors' MoGlow, timed with its own sampling loop, for bench_models.py to measure
beside ours in the same run.

Their code (github.com/simonalexanderson/StyleGestures) is obtained separately and never
part of this repository; ``$MOGLOW_REFERENCE_CODE`` names a checkout of it. The model is
their ``glow.models.Glow`` built from their ``hparams/paper_version/locomotion.json`` (the
paper's locomotion model: 16 steps, LSTM 2×512, 10 past poses) on the CPU, with our pose
and control sizes, and a sampling run is their ``glow.generator.Generator.generate_sample``
(the loop they sample their figures' animations with) on ``frames`` frames of control,
starting from the mean pose as ours does. Only the animation file it writes at the end is
left out: the data object here keeps the sampled array instead.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ENVIRONMENT_VARIABLE = "MOGLOW_REFERENCE_CODE"


def reference_code() -> Path | None:
    """The checkout named by $MOGLOW_REFERENCE_CODE, or None when it is not set.

    A path that is set but holds no ``glow/models.py`` is an error, not a silent fallback."""
    value = os.environ.get(ENVIRONMENT_VARIABLE)
    if not value:
        return None
    path = Path(value).expanduser().resolve()
    if not (path / "glow" / "models.py").is_file():
        raise FileNotFoundError(f"${ENVIRONMENT_VARIABLE}={value}: no glow/models.py there "
                                "(expected a checkout of github.com/simonalexanderson/StyleGestures)")
    return path


class _TestData:
    """What their Generator asks of a data set: a test set of (autoreg, control) sequences,
    and somewhere to put the sampled animation."""

    def __init__(self, pose: np.ndarray, control: np.ndarray) -> None:
        self.items = [{"autoreg": p, "control": c} for p, c in zip(pose, control)]
        self.sampled: np.ndarray | None = None

    def get_test_dataset(self) -> list[dict[str, np.ndarray]]:
        return self.items

    def save_animation(self, control: np.ndarray, sampled: np.ndarray, filename: str) -> None:
        self.sampled = sampled


class ReferenceSampler:
    """Their paper-sized model and sampling loop for ``batch`` sequences of ``control``
    (frames × control_dim, repeated), poses of ``pose_dim`` features."""

    def __init__(self, code: Path, control: np.ndarray, pose_dim: int, batch: int) -> None:
        if str(code) not in sys.path:
            sys.path.insert(0, str(code))
        import torch
        from glow.config import JsonConfig
        from glow.generator import Generator
        from glow.models import Glow

        settings = json.loads((code / "hparams" / "paper_version" / "locomotion.json").read_text())
        settings["Device"] = {"glow": ["cpu"], "data": "cpu"}
        settings["Train"]["batch_size"] = batch
        hparams = JsonConfig(settings)
        seqlen = hparams.Data.seqlen
        frames, control_dim = control.shape
        control = np.repeat(control[None].astype(np.float32), batch, axis=0)
        pose = np.zeros((batch, frames, pose_dim), np.float32)
        self.data = _TestData(pose, control)
        with contextlib.redirect_stdout(io.StringIO()):  # their constructors print each layer
            torch.manual_seed(0)
            self.graph = Glow(pose_dim, seqlen * pose_dim + (seqlen + 1) * control_dim, hparams).eval()
            self.graph.set_actnorm_init(True)  # as after training: no initialisation from the first batch
            self.generator = Generator(self.data, "cpu", "", hparams)
        self.parameters = sum(p.numel() for p in self.graph.parameters())
        self.frames = frames - seqlen  # generated per sequence, as ours generates frames - tau
        self.batch = batch

    def seconds(self) -> float:
        """Wall time of one sampling run of the batch."""
        self.data.sampled = None
        with contextlib.redirect_stdout(io.StringIO()):
            start = time.perf_counter()
            self.generator.generate_sample(self.graph, eps_std=1.0)
            elapsed = time.perf_counter() - start
        sampled = self.data.sampled
        if sampled is None or sampled.shape[0] != self.batch or not np.isfinite(sampled).all():
            raise RuntimeError("the reference sampling loop returned no finite animation")
        return elapsed
