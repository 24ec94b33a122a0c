"""Checkpoints, training, resuming and the Generator, with a tiny MoGlow on real clips."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import torch

from generation import registry
from generation.checkpoint import CheckpointError, load_checkpoint, read_meta, save_checkpoint
from generation.control import load_control_file, preset_path
from generation.generator import Generator
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.train import TrainOptions, train

pytestmark = pytest.mark.slow

CLIPS = ["walk_normal_001", "walk_happy_001", "walk-back_normal_001", "run_normal_001", "walk-left_old_001", "walk_old_002"]


@pytest.fixture(scope="module")
def clips_folder(motion_data, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("clips")
    for name in CLIPS:
        for suffix in (".bvh", ".json"):
            (folder / f"dataset-1_{name}{suffix}").symlink_to(motion_data / "data" / f"dataset-1_{name}{suffix}")
    (folder / "cfg").symlink_to(motion_data / "cfg")
    return folder


@pytest.fixture(scope="module")
def dataset(clips_folder, tmp_path_factory):
    return build_dataset(clips_folder, DatasetOptions(holdout_fraction=0.2), cache_dir=tmp_path_factory.mktemp("cache"), progress=False)


@pytest.fixture(scope="module")
def tiny_preset(monkeypatch_module):
    """A MoGlow small enough to train in seconds, registered as the preset 'tiny'."""
    presets = registry.MODELS["moglow"].presets
    cpu = presets["cpu"]
    tiny = registry.Preset({**cpu.model, "steps": 2, "tau": 3, "lstm_hidden": 16},
                           {**cpu.training, "batch_size": 8, "warmup_steps": 0})
    monkeypatch_module.setitem(presets, "tiny", tiny)
    return "tiny"


@pytest.fixture(scope="module")
def monkeypatch_module():
    patch = pytest.MonkeyPatch()
    yield patch
    patch.undo()


@pytest.fixture(scope="module")
def checkpoint(dataset, tiny_preset, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("run") / "moglow.safetensors"
    train("moglow", tiny_preset, dataset, path, TrainOptions(steps=20, eval_every=10), progress=False)
    return path


def test_training_writes_a_checkpoint_describing_model_data_and_progress(checkpoint, dataset):
    meta = read_meta(checkpoint)
    assert meta.kind == "moglow" and meta.step == 20 and meta.pose_dim == 63 and meta.control_dim == 3
    assert meta.data_fingerprint == dataset.fingerprint
    assert [h["step"] for h in meta.metrics["history"]] == [10, 20]
    assert np.isfinite(meta.metrics["val_loss"])
    assert meta.skeleton["names"][0] == "Hips" and len(meta.stats["pose"]["mean"]) == 63
    assert meta.code_version
    assert Path(str(checkpoint).replace(".safetensors", ".optim.safetensors")).is_file()
    best = read_meta(Path(str(checkpoint).replace(".safetensors", ".best.safetensors")))
    assert best.metrics["val_loss"] == min(h["val_loss"] for h in meta.metrics["history"])


def test_resuming_continues_from_the_saved_step(checkpoint, dataset, tiny_preset, tmp_path):
    copy = tmp_path / "resumed.safetensors"
    copy.write_bytes(checkpoint.read_bytes())
    (tmp_path / "resumed.optim.safetensors").write_bytes(
        Path(str(checkpoint).replace(".safetensors", ".optim.safetensors")).read_bytes())
    meta = train("moglow", tiny_preset, dataset, copy, TrainOptions(steps=30, eval_every=10), resume=True, progress=False)
    assert meta.step == 30 and [h["step"] for h in meta.metrics["history"]] == [10, 20, 30]


def _copy_with_optimiser(checkpoint: Path, to: Path) -> Path:
    to.write_bytes(checkpoint.read_bytes())
    to.with_name(to.name.replace(".safetensors", ".optim.safetensors")).write_bytes(
        Path(str(checkpoint).replace(".safetensors", ".optim.safetensors")).read_bytes())
    return to


def test_resuming_with_a_changed_setting_continues_the_run_under_it_and_records_from_which_step(
        checkpoint, dataset, tiny_preset, tmp_path):
    copy = _copy_with_optimiser(checkpoint, tmp_path / "changed.safetensors")
    meta = train("moglow", tiny_preset, dataset, copy, TrainOptions(steps=30, eval_every=10), resume=True,
                 progress=False, overrides={"dropout": 0.7, "learning_rate": 1e-3})
    assert meta.step == 30 and meta.metrics["history"][:2] == read_meta(checkpoint).metrics["history"]
    assert meta.hyperparameters["dropout"] == 0.7 and meta.training["learning_rate"] == 1e-3
    assert meta.metrics["changes"] == [{"step": 20, "dropout": 0.7, "learning_rate": 1e-3}]
    resumed = train("moglow", tiny_preset, dataset, copy, TrainOptions(steps=40, eval_every=10), resume=True, progress=False,
                    overrides={"dropout": 0.7})  # as a script resumed with the same --set: no new change
    assert resumed.hyperparameters["dropout"] == 0.7 and resumed.metrics["changes"] == meta.metrics["changes"]


def test_resuming_with_a_change_to_the_architecture_is_refused_naming_the_setting(checkpoint, dataset, tiny_preset, tmp_path):
    copy = _copy_with_optimiser(checkpoint, tmp_path / "wider.safetensors")
    untouched = copy.read_bytes()
    with pytest.raises(CheckpointError, match="cannot change lstm_hidden when resuming"):
        train("moglow", tiny_preset, dataset, copy, TrainOptions(steps=30, eval_every=10), resume=True,
              progress=False, overrides={"lstm_hidden": 32})
    assert copy.read_bytes() == untouched


@pytest.mark.parametrize(("setting", "message"), [
    ("nope=1", "moglow has no setting nope (model: dropout, lstm_hidden,"),
    ("dropout=high", "setting dropout must be float, not 'high'"),
    ("batch_size=1.5", "setting batch_size must be int, not 1.5"),
    ("batch_size=0", "batch_size must be positive, not 0"),
    ("steps=0", "steps must be at least 1, not 0"),
])
def test_train_command_refuses_a_setting_it_cannot_use_before_training(clips_folder, tmp_path, capsys, setting, message):
    from generation.cli import main

    out = tmp_path / "model.safetensors"
    assert main(["train", str(clips_folder), "--out", str(out), "--steps", "1", "--cache-dir", str(tmp_path / "cache"),
                 "--set", setting]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_train_command_takes_settings_for_the_model_and_the_training(clips_folder, tiny_preset, tmp_path, capsys):
    from generation.cli import main

    out = tmp_path / "model.safetensors"
    assert main(["train", str(clips_folder), "--preset", tiny_preset, "--out", str(out), "--steps", "2",
                 "--eval-every", "2", "--cache-dir", str(tmp_path / "cache"), "--set", "dropout=0.95",
                 "--set", "batch_size=4"]) == 0, capsys.readouterr().err
    meta = read_meta(out)
    assert meta.hyperparameters["dropout"] == 0.95 and meta.training["batch_size"] == 4
    assert "changes" not in meta.metrics  # settings of a new run are its configuration, not changes


def test_the_model_configuration_and_the_training_knobs_are_recorded_apart(checkpoint):
    meta = read_meta(checkpoint)
    assert meta.training == {"learning_rate": 3e-3, "grad_clip": 100.0, "batch_size": 8, "warmup_steps": 0, "classifiers": ""}
    assert meta.hyperparameters == {"steps": 2, "tau": 3, "lstm_hidden": 16, "lstm_layers": 2, "dropout": 0.3,
                                    "scale_offset": 0.0, "scale_floor": 0.05}


def _move_training_into_hyperparameters(header):
    """The header as checkpoints wrote it when the training knobs were model hyperparameters."""
    meta = json.loads(header["__metadata__"]["motion_study"])
    training = meta.pop("training")
    training.pop("classifiers")  # MoGlow's configuration never had it
    meta["hyperparameters"].update(training)
    header["__metadata__"]["motion_study"] = json.dumps(meta)


def test_a_header_with_training_knobs_among_the_hyperparameters_is_read_and_resumed(checkpoint, dataset, tiny_preset, tmp_path):
    old = _rewrite_header(checkpoint, tmp_path / "old.safetensors", _move_training_into_hyperparameters)
    data = old.read_bytes()
    (length,) = struct.unpack("<Q", data[:8])
    assert "learning_rate" in json.loads(json.loads(data[8 : 8 + length])["__metadata__"]["motion_study"])["hyperparameters"]
    (tmp_path / "old.optim.safetensors").write_bytes(
        Path(str(checkpoint).replace(".safetensors", ".optim.safetensors")).read_bytes())
    meta = read_meta(old)
    assert meta.training == {"learning_rate": 3e-3, "grad_clip": 100.0, "batch_size": 8, "warmup_steps": 0}
    assert meta.hyperparameters == read_meta(checkpoint).hyperparameters
    resumed = train("moglow", tiny_preset, dataset, old, TrainOptions(steps=30, eval_every=10), resume=True, progress=False)
    assert resumed.step == 30 and resumed.training == read_meta(checkpoint).training


def test_the_committed_checkpoint_still_reads_loads_and_samples():
    path = Path(__file__).resolve().parent.parent / "models" / "moglow-cpu.safetensors"
    meta = read_meta(path)
    assert meta.training == {"learning_rate": 3e-3, "warmup_steps": 100, "grad_clip": 100.0, "batch_size": 32,
                             "classifiers": ""}
    assert "learning_rate" not in meta.hyperparameters and meta.hyperparameters["lstm_hidden"] == 128
    control = preset_path("walk-straight")
    motion = Generator.load(path).sample(control, seed=0)[0]
    assert motion.positions.shape == (control.n_frames, 21, 3) and np.isfinite(motion.positions).all()


def test_samples_are_reproducible_and_survive_save_and_load(checkpoint, tmp_path):
    generator = Generator.load(checkpoint)
    control = preset_path("walk-circle")
    a = generator.sample(control, n=2, seed=7)
    b = generator.sample(control, n=2, seed=7)
    c = generator.sample(control, n=2, seed=8)
    assert len(a) == 2 and a[0].positions.shape == (control.n_frames, 21, 3) and a[0].fps == 20.0
    np.testing.assert_array_equal(a[0].positions, b[0].positions)
    assert not np.allclose(a[0].positions, c[0].positions)
    assert not np.allclose(a[0].positions, a[1].positions)  # two different samples

    model, meta = load_checkpoint(checkpoint)
    copy = save_checkpoint(tmp_path / "copy.safetensors", model, meta)
    again = Generator.load(copy).sample(control, n=2, seed=7)
    np.testing.assert_array_equal(again[1].positions, a[1].positions)


def test_generated_root_follows_the_control_path(checkpoint):
    control = preset_path("walk-straight")
    motion = Generator.load(checkpoint).sample(control, seed=1)[0]
    # The pose is placed on the integrated path: the hips end up near the path's end.
    end = control.path().xz[-1]
    assert np.linalg.norm(motion.positions[-1, 0, [0, 2]] - end) < 100


def _rewrite_header(path: Path, out: Path, change) -> Path:
    data = path.read_bytes()
    (length,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + length])
    change(header)
    text = json.dumps(header).encode()
    out.write_bytes(struct.pack("<Q", len(text)) + text + data[8 + length :])
    return out


def _set_meta(field, value):
    def change(header):
        meta = json.loads(header["__metadata__"]["motion_study"])
        meta[field] = value
        header["__metadata__"]["motion_study"] = json.dumps(meta)
    return change


@pytest.mark.parametrize("tamper, message", [
    (lambda p, out: out.write_bytes(p.read_bytes()[:-100]) and out, "not a readable safetensors file"),
    (lambda p, out: out.write_bytes(p.read_bytes()[:-8] + b"\x00" * 8) and out, "do not match the checkpoint's digest"),
    (lambda p, out: _rewrite_header(p, out, _set_meta("kind", "gan")), "unknown model kind 'gan'"),
    (lambda p, out: _rewrite_header(p, out, _set_meta("pose_dim", 60)), "the model.s pose features have 60"),
    (lambda p, out: _rewrite_header(p, out, lambda h: h["__metadata__"].pop("motion_study")), "not a checkpoint of this project"),
])
def test_tampered_checkpoints_fail_with_a_message_naming_the_problem(checkpoint, tmp_path, tamper, message):
    bad = tamper(checkpoint, tmp_path / "bad.safetensors")
    with pytest.raises(CheckpointError, match=message) as error:
        load_checkpoint(bad)
    assert str(bad) in str(error.value)


def test_a_checkpoint_with_a_missing_tensor_is_refused(checkpoint, tmp_path):
    from safetensors.torch import load_file, save_file

    from generation.checkpoint import FORMAT_KEY
    from generation.store import tensor_digest

    tensors = load_file(str(checkpoint))
    tensors.pop(sorted(tensors)[0])
    meta = read_meta(checkpoint)
    save_file(tensors, str(tmp_path / "short.safetensors"),
              metadata={FORMAT_KEY: meta.to_json(), "digest": tensor_digest(tensors)})
    with pytest.raises(CheckpointError, match="missing tensor"):
        load_checkpoint(tmp_path / "short.safetensors")


def test_loading_never_unpickles(checkpoint, monkeypatch):
    import pickle

    def refuse(*args, **kwargs):
        raise AssertionError("unpickling attempted")

    monkeypatch.setattr(pickle, "load", refuse)
    monkeypatch.setattr(pickle, "loads", refuse)
    monkeypatch.setattr(torch, "load", refuse)
    model, _ = load_checkpoint(checkpoint)
    assert not model.training


def assert_rotation_bvh_following(path: Path, positions: np.ndarray, skeleton: dict, scale: float = 1.0) -> None:
    """``path`` holds the root's position and every joint's rotation on the training rig:
    read back, the root is where the sample's is, every bone has the rig's length, and
    every joint with one bone points it where the sample's does."""
    from generation.motion import read_bvh

    bvh = read_bvh(path)
    assert bvh.skeleton.names == tuple(skeleton["names"])
    assert [len(names) for names in bvh.channels] == [6] + [3] * (len(bvh.channels) - 1)
    read = bvh.to_motion(scale).positions
    np.testing.assert_allclose(read[:, 0], positions[:, 0], atol=1e-4)
    parents, offsets = np.asarray(skeleton["parents"]), np.asarray(skeleton["offsets"])
    for child, parent in enumerate(parents[1:], start=1):
        bone = read[:, child] - read[:, parent]
        np.testing.assert_allclose(np.linalg.norm(bone, axis=-1), np.linalg.norm(offsets[child]), atol=1e-4)
        if np.sum(parents == parent) == 1:
            sampled = positions[:, child] - positions[:, parent]
            np.testing.assert_allclose(bone / np.linalg.norm(bone, axis=-1, keepdims=True),
                                       sampled / np.linalg.norm(sampled, axis=-1, keepdims=True), atol=1e-5)


def test_sample_command_writes_npz_bvh_and_video_per_clip(checkpoint, tmp_path, capsys):
    from generation.cli import main

    control_file = tmp_path / "turn.yaml"
    control_file.write_text("segments:\n  - {type: curve, speed: 100, turn_rate: 30, seconds: 2}\n")
    out = tmp_path / "samples"
    code = main(["sample", str(checkpoint), "-c", "stand-still", str(control_file), "--n", "2", "--out", str(out),
                 "--render", "--size", "160x120"])
    assert code == 0, capsys.readouterr().err
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(f"{stem}_{i:02d}.{ext}" for stem in ("stand-still", "turn-0") for i in range(2) for ext in ("bvh", "mp4", "npz"))
    with np.load(out / "turn-0_01.npz") as clip:
        assert clip["positions"].shape == (40, 21, 3) and float(clip["fps"]) == 20.0
        assert_rotation_bvh_following(out / "turn-0_01.bvh", clip["positions"], read_meta(checkpoint).skeleton)
        asked = load_control_file(control_file)[0].path()  # what the control adherence compares the root with
        np.testing.assert_allclose(clip["control_path"], asked.xz)
        np.testing.assert_allclose(clip["control_yaw"], asked.yaw)
        assert clip["root_path"].shape == (40, 2) and clip["root_yaw"].shape == (40,)


def test_sample_draws_each_clips_own_control_or_the_control_shown_and_refuses_one_of_another_length(
        checkpoint, tmp_path, monkeypatch, capsys):
    from generation.cli import main, models

    drawn = []
    monkeypatch.setattr(models, "render_video", lambda motion, path, **kwargs: drawn.append(kwargs))
    assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(tmp_path / "own"),
                 "--draw-control"]) == 0
    assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(tmp_path / "shown"),
                 "--draw-control", "walk-circle"]) == 0
    for kwargs, shown in zip(drawn, ("walk-straight", "walk-circle")):
        np.testing.assert_allclose(kwargs["control_path"], preset_path(shown).path().xz)
    assert not np.allclose(drawn[0]["root_path"], drawn[0]["control_path"])  # the figure's own path, drawn over it
    short = tmp_path / "short.yaml"
    short.write_text("segments:\n  - {type: straight, speed: 100, seconds: 2}\n")
    assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(tmp_path / "x"),
                 "--draw-control", str(short)]) == 2
    assert f"--draw-control {short} lasts 40 frames, the control walk-straight 80" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.fixture
def one_torch_thread():
    """Small networks train in a second on one thread and far slower on several cores
    that other work shares."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.mark.parametrize("kind", ["rnn", "vae"])
def test_sample_command_writes_rotation_bvh_for_the_path_baselines_too(kind, dataset, tmp_path, one_torch_thread):
    from generation.cli import main

    path = tmp_path / f"{kind}.safetensors"
    train(kind, "cpu", dataset, path, TrainOptions(steps=2, eval_every=2), progress=False,
          overrides={"hidden_size": 16, "batch_size": 8})
    out = tmp_path / "samples"
    assert main(["sample", str(path), "-c", "walk-straight", "--out", str(out)]) == 0
    with np.load(out / "walk-straight_00.npz") as clip:
        assert_rotation_bvh_following(out / "walk-straight_00.bvh", clip["positions"], read_meta(path).skeleton)


def test_sample_command_writes_bvh_in_the_unit_asked_for_and_says_which(checkpoint, tmp_path, capsys):
    from generation.cli import main
    from generation.motion.unit_detection import choose_units
    from generation.motion.skeleton_units import Units

    out = tmp_path / "in-metres"
    assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(out), "--bvh-unit", "m"]) == 0
    said = capsys.readouterr()
    assert f"1 clips in {out} (BVH lengths in metres, npz in centimetres; y up)" in said.out
    assert "note: the model learnt from BVH files in centimetres; --bvh-unit cm writes" in said.err
    bvh = out / "walk-straight_00.bvh"
    assert choose_units([bvh]).units == Units(100.0, "y")
    with np.load(out / "walk-straight_00.npz") as clip:
        assert_rotation_bvh_following(bvh, clip["positions"], read_meta(checkpoint).skeleton, scale=100.0)


def test_sample_command_warmup_seconds_changes_what_precedes_the_kept_clip(checkpoint, tmp_path, capsys):
    from generation.cli import main

    def sampled(*extra: str) -> np.ndarray:
        out = tmp_path / "-".join(extra or ("default",))
        assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(out), *extra]) == 0, capsys.readouterr().err
        with np.load(out / "walk-straight_00.npz") as clip:
            return clip["positions"]

    default, one_second, none = sampled(), sampled("--warmup-seconds", "1"), sampled("--warmup-seconds", "0")
    np.testing.assert_array_equal(default, one_second)  # MoGlow's default is the paper's one second
    assert none.shape == default.shape and not np.allclose(none, default)


@pytest.mark.parametrize(("bfloat16_units", "chosen"), [(True, "bfloat16"), (False, "float32")])
def test_sample_command_samples_in_the_precision_auto_chose_and_says_which(checkpoint, tmp_path, capsys, monkeypatch,
                                                                             bfloat16_units, chosen):
    from generation.cli import main
    from generation.models import precision

    if bfloat16_units and not precision.cpu_has_bfloat16_units():  # the choice is faked, the products are not
        pytest.skip("this CPU has no bfloat16 units for oneDNN's products (no AVX-512 BF16 or AVX-NE-CONVERT)")
    monkeypatch.setattr(precision, "cpu_has_bfloat16_units", lambda: bfloat16_units)

    def sampled(name: str, *extra: str) -> np.ndarray:
        out = tmp_path / name
        assert main(["sample", str(checkpoint), "-c", "walk-straight", "--out", str(out), *extra]) == 0
        with np.load(out / "walk-straight_00.npz") as clip:
            return clip["positions"]

    auto = sampled("auto")
    assert f"sampling in {chosen} (--precision auto)" in capsys.readouterr().err
    np.testing.assert_array_equal(auto, sampled(chosen, "--precision", chosen))
    assert not np.array_equal(auto, sampled("int8", "--precision", "int8"))


def test_evaluate_command_reports_held_out_nll(checkpoint, clips_folder, dataset, tmp_path, capsys):
    from generation.cli import main

    assert main(["evaluate", str(checkpoint), "--data", str(clips_folder), "--cache-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "held-out negative log-likelihood (nats per frame)" in out
    value = float(out.split(":")[-1].split()[0])
    # The test takes, not the validation takes that training chose its checkpoints on.
    model, _ = load_checkpoint(checkpoint)
    test = {k: torch.as_tensor(v) for k, v in dataset.windows("test").items()}
    with torch.no_grad():
        expected = -model.log_likelihood(test["pose"], test["control"]).mean().item()
    assert value == pytest.approx(expected, rel=1e-4)
    assert value != pytest.approx(read_meta(checkpoint).metrics["val_loss"], rel=1e-3)


def test_a_broken_checkpoint_is_a_clean_command_line_error(tmp_path, capsys):
    from generation.cli import main

    bad = tmp_path / "model.safetensors"
    bad.write_bytes(b"not a checkpoint")
    assert main(["sample", str(bad), "--out", str(tmp_path / "out")]) == 2
    assert f"{bad}: not a readable safetensors file" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
