"""Hostile checkpoints and sampling requests: each refused naming the field or tensor, on the
command line (exit status 2) and at the web upload (400, nothing stored).

The checkpoints are a tiny MoGlow with the committed model's description (statistics,
skeleton, data options), made in milliseconds, then altered the way an attacker or a
broken exporter would, with a digest that matches the altered tensors.
"""

from __future__ import annotations

import dataclasses
import json
import resource
import struct
import time
from pathlib import Path

import pytest
import torch
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from safetensors.torch import load_file, save_file

from generation.checkpoints.checkpoint import FORMAT_KEY, read_meta, save_checkpoint
from generation.checkpoints.store import tensor_digest
from generation.cli import main
from generation.registry import model_class
from studyapp.models import Study, System

REPO = Path(__file__).resolve().parents[1]
COMMITTED = REPO / "models" / "moglow-cpu.safetensors"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    """A MoGlow of a few thousand parameters, described as the committed one is."""
    meta = read_meta(COMMITTED)
    cls = model_class("moglow")
    config = dataclasses.replace(cls.Config(**meta.hyperparameters), steps=2, lstm_hidden=8, lstm_layers=1, tau=2)
    torch.manual_seed(0)
    model = cls(config, meta.pose_dim, meta.control_dim)
    path = tmp_path_factory.mktemp("tiny") / "tiny.safetensors"
    return save_checkpoint(path, model, dataclasses.replace(meta, hyperparameters=dataclasses.asdict(config)))


def rewritten(source: Path, out: Path, description=None, tensors=None) -> Path:
    """``source`` with its JSON description and tensors changed, and a digest to match."""
    weights = load_file(str(source))
    if tensors is not None:
        tensors(weights)
    meta = json.loads(read_meta(source).to_json())
    if description is not None:
        description(meta)
    save_file(weights, str(out), metadata={FORMAT_KEY: json.dumps(meta), "digest": tensor_digest(weights)})
    return out


def _first(weights: dict) -> str:
    return next(name for name in sorted(weights) if weights[name].is_floating_point() and weights[name].numel() > 1)


def _set_nan(weights):
    weights[_first(weights)][0] = float("nan")


def _to_int8(weights):
    for name in list(weights):
        weights[name] = weights[name].to(torch.int8)


def _huge(meta):
    meta["hyperparameters"].update(lstm_hidden=40_000, lstm_layers=8, steps=64)


HOSTILE_CHECKPOINTS = {
    "a huge model in a small file": (dict(description=_huge), "describe a model larger than the file's"),
    "NaN weights": (dict(tensors=_set_nan), "NaN or infinite value(s)"),
    "int8 weights": (dict(tensors=_to_int8), "is int8, the model needs float32"),
    "NaN standardisation": (dict(description=lambda m: m["stats"]["pose"]["mean"].__setitem__(0, float("nan"))),
                            "stats.pose.mean holds NaN or infinity"),
    "short standardisation": (dict(description=lambda m: m["stats"]["control"]["std"].pop()),
                              "stats.control.std has 2 values; the model's control features have 3"),
    "zero std": (dict(description=lambda m: m["stats"]["pose"]["std"].__setitem__(3, 0.0)),
                 "stats.pose.std must be positive"),
    "fps 0": (dict(description=lambda m: m["features"]["dataset_options"].update(fps=0.0)),
              "features.dataset_options: dataset option fps must be"),
    "fps Infinity": (dict(description=lambda m: m["features"]["dataset_options"].update(fps=float("inf"))),
                     "features.dataset_options: dataset option fps must be"),
    "an empty skeleton": (dict(description=lambda m: m.update(skeleton={"names": [], "parents": [], "offsets": []})),
                          "skeleton has no joints"),
    "a skeleton without parents": (dict(description=lambda m: m["skeleton"].pop("parents")), "skeleton: KeyError"),
}


@pytest.mark.parametrize("change, message", HOSTILE_CHECKPOINTS.values(), ids=HOSTILE_CHECKPOINTS.keys())
def test_a_hostile_checkpoint_on_the_command_line_exits_2_naming_the_problem(change, message, tiny, tmp_path, capsys):
    bad = rewritten(tiny, tmp_path / "bad.safetensors", **change)
    for command in (["sample", str(bad), "--out", str(tmp_path / "out")],
                    ["evaluate", str(bad), "--data", str(tmp_path)]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert f"{bad}: " in err and message in err, err
    assert not (tmp_path / "out").exists()


def test_a_huge_model_in_a_small_file_is_refused_quickly_without_allocating(tiny, tmp_path, capsys):
    bad = rewritten(tiny, tmp_path / "huge.safetensors", description=_huge)
    assert bad.stat().st_size < 1_000_000  # a few hundred KB of statistics and a tiny model's tensors
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    started = time.perf_counter()
    assert main(["sample", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert time.perf_counter() - started < 2.0  # the model it describes would take minutes to build
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 100_000  # KiB: nothing big allocated
    assert "describe a model larger than the file's" in capsys.readouterr().err


HOSTILE_SAMPLING = {
    "temperature -1": (["--temperature", "-1"], "temperature must be"),
    "temperature nan": (["--temperature", "nan"], "temperature must be"),
    "warm-up 1e9 s": (["--warmup-seconds", "1e9"], "warmup_seconds must be"),
    "n 0": (["--n", "0"], "n must be at least 1"),
    "a control lasting forever": (["--control", "CONTROL_FILE"], "segment 0: 'seconds' must be a finite number"),
}


@pytest.mark.parametrize("extra, message", HOSTILE_SAMPLING.values(), ids=HOSTILE_SAMPLING.keys())
def test_hostile_sampling_options_exit_2_naming_the_option(extra, message, tiny, tmp_path, capsys):
    control = tmp_path / "forever.json"
    control.write_text('{"segments": [{"type": "straight", "seconds": Infinity}]}')
    extra = [str(control) if word == "CONTROL_FILE" else word for word in extra]
    assert main(["sample", str(tiny), "--out", str(tmp_path / "out"), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


@pytest.fixture
def study(client, settings, tmp_path) -> Study:
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    owner = User.objects.create_user("researcher")
    client.force_login(owner)
    return Study.objects.create(owner=owner, title="Gait", video_width=160, video_height=120)


@pytest.mark.django_db
@pytest.mark.parametrize("change, message", HOSTILE_CHECKPOINTS.values(), ids=HOSTILE_CHECKPOINTS.keys())
def test_a_hostile_checkpoint_upload_is_a_400_naming_the_problem_and_stores_nothing(change, message, tiny, study,
                                                                                      client, tmp_path):
    bad = rewritten(tiny, tmp_path / "bad.safetensors", **change)
    response = client.post(f"/studies/{study.pk}/systems/", {
        "action": "checkpoint", "name": "MoGlow", "role": "model", "temperature": "1.0",
        "checkpoint": SimpleUploadedFile("model.safetensors", bad.read_bytes())})
    assert response.status_code == 400
    page = response.content.decode()
    assert f"model.safetensors: " in page and message.replace("'", "&#x27;") in page
    assert str(tmp_path) not in page
    assert not System.objects.exists()
    assert not (tmp_path / "checkpoints").exists() or not list((tmp_path / "checkpoints").iterdir())


def test_evaluate_refuses_a_held_out_loss_that_is_not_finite(tiny, motion_data, tmp_path, capsys):
    def blow_up(weights):  # finite weights whose outputs overflow
        for name in weights:
            if weights[name].is_floating_point():
                weights[name] = weights[name] * 1e30

    bad = rewritten(tiny, tmp_path / "overflowing.safetensors", tensors=blow_up)
    assert main(["evaluate", str(bad), "--data", str(motion_data), "--cache-dir", str(tmp_path / "cache")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: the held-out negative log-likelihood (nats per frame) is " in err and "overflow" in err


def _framed(header: bytes) -> bytes:
    """A safetensors file of ``header`` and no tensors: its length, then the header."""
    return struct.pack("<Q", len(header)) + header


NESTED = "[" * 100_000 + "]" * 100_000


@pytest.mark.django_db
@pytest.mark.parametrize("data, message", [
    (_framed(NESTED.encode()), "model.safetensors: not a readable safetensors file"),
    (_framed(json.dumps({"__metadata__": {FORMAT_KEY: NESTED, "digest": "0"}}).encode()),
     "model.safetensors: the checkpoint&#x27;s JSON header is nested too deeply"),
], ids=["the safetensors header", "the checkpoint's description"])
def test_a_checkpoint_header_nested_past_the_parsers_stack_is_a_400_naming_it(data, message, study, client, tmp_path):
    response = client.post(f"/studies/{study.pk}/systems/", {
        "action": "checkpoint", "name": "MoGlow", "role": "model", "temperature": "1.0",
        "checkpoint": SimpleUploadedFile("model.safetensors", data)})
    assert response.status_code == 400 and message in response.content.decode()
    assert not System.objects.exists()
