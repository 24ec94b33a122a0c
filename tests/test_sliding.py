"""`generation sliding`: where a MoGlow's foot sliding arises, on held-out takes."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import torch

from measures.feet import lower_foot_speed
from generation.cli import main
from generation.motion.clip_files import load_body_motion
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from tests.test_checkpoint import checkpoint, clips_folder, dataset, monkeypatch_module, tiny_preset  # noqa: F401

CONTENTS = "walk,walk-back,run,walk-left"


def speeds(output: str) -> dict[str, float]:
    return {m[1].strip(): float(m[2]) for m in re.finditer(r"^  (\S.*?)\s+([\d.]+) cm/s", output, re.M)}


def test_sliding_measures_four_versions_of_each_take_and_the_take_as_its_bvh_moves(checkpoint, clips_folder,  # noqa: F811
                                                                                  tmp_path, capsys):
    args = ["sliding", str(checkpoint), "--data", str(clips_folder), "--contents", CONTENTS, "--seconds", "3",
            "--samples", "2", "--cache-dir", str(tmp_path / "cache")]
    assert main(args) == 0, capsys.readouterr().err
    output = capsys.readouterr().out
    measured = speeds(output)
    assert list(measured) == ["natural", "one frame ahead, T=0", "from the take's poses, T=0",
                              "from the take's poses, T=1", "from the mean pose, T=1", "mean pose + warm-up, T=1"]
    assert all(math.isfinite(v) and v > 0 for v in measured.values())

    # The natural row, computed independently: the held-out takes' own BVH, at the model's
    # frame rate, from 1 s (frame 20) on, at the toes.
    held_out = build_dataset(clips_folder, DatasetOptions(holdout_fraction=0.2), cache_dir=tmp_path / "cache",
                             progress=False).select("test", augmented=False)
    held_out = [c for c in held_out if c.content in CONTENTS.split(",")]
    assert f"of {len(held_out)} held-out" in output and len(held_out) >= 1
    motions = [load_body_motion(clips_folder / f"{c.name}.bvh", 20.0, 3.0) for c in held_out]
    toes = [i for i, name in enumerate(motions[0].skeleton.names) if name.startswith("Toes")]
    expected = lower_foot_speed([m.positions[20:] for m in motions], 20.0, toes)
    assert np.isclose(measured["natural"], round(expected, 1), atol=0.051)


@pytest.mark.parametrize(("given", "message"), [
    ([], "the measurement needs the motion folder: --data FOLDER or $MOTION_DATA"),
    (["--takes", "0"], "--takes and --samples must be at least 1 and --seconds positive, not 0, 8 and 6"),
    (["--samples", "0"], "--takes and --samples must be at least 1 and --seconds positive, not 12, 0 and 6"),
])
def test_sliding_without_data_or_with_nothing_to_measure_is_refused_with_exit_2(checkpoint, monkeypatch, capsys,  # noqa: F811
                                                                                given, message):
    monkeypatch.delenv("MOTION_DATA", raising=False)
    assert main(["sliding", str(checkpoint), *given]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_sliding_on_a_gpu_measures_what_the_cpu_measures(checkpoint, clips_folder, tmp_path, capsys):  # noqa: F811
    def measure(device: str) -> dict[str, float]:
        args = ["sliding", str(checkpoint), "--data", str(clips_folder), "--contents", CONTENTS, "--seconds", "3",
                "--samples", "2", "--cache-dir", str(tmp_path / "cache"), "--device", device]
        assert main(args) == 0, capsys.readouterr().err
        return speeds(capsys.readouterr().out)

    on_cpu, on_gpu = measure("cpu"), measure("cuda")
    assert list(on_gpu) == list(on_cpu)
    assert on_gpu["natural"] == on_cpu["natural"]
    # At temperature 0 nothing is drawn: the same model predicts the same frames, up to
    # the GPU's float32 rounding; at temperature 1 the noise comes from the GPU's generator.
    for condition in ("one frame ahead, T=0", "from the take's poses, T=0"):
        assert on_gpu[condition] == pytest.approx(on_cpu[condition], rel=0.02, abs=0.2)
    assert all(math.isfinite(v) and v > 0 for v in on_gpu.values())


@pytest.mark.skipif(torch.cuda.is_available(), reason="a CUDA device is present")
def test_sliding_on_a_gpu_that_is_not_there_is_refused_with_exit_2(checkpoint, clips_folder, capsys):  # noqa: F811
    assert main(["sliding", str(checkpoint), "--data", str(clips_folder), "--device", "cuda"]) == 2
    assert "--device cuda asked for, but torch sees no CUDA device" in capsys.readouterr().err
