"""Choosing a study's control signals: held out from the motion data, or synthetic.

Held-out controls come from the test split of the very dataset the study's checkpoints
were trained on (same files, same options, so the same split): the models never saw
these clips, and the NAT system shows the clip each one came from. Synthetic controls
are ``generation.control``'s presets or a JSON/YAML description. Both follow the frame
rate the checkpoints were trained at. Adding a control again is harmless; adding a
different control under a taken name is refused.
"""

from __future__ import annotations

import json
import tempfile
from itertools import zip_longest
from pathlib import Path

from django.conf import settings
from django.core.files import File

from generation.control import PathControl, held_out_paths, load_control_file, preset_path
from generation.motion.dataset import DatasetOptions, build_dataset, find_bvh_files
from studyapp.models import ControlSignal, Study

CONTROL_FILE_SUFFIXES = (".json", ".yaml", ".yml")
MAX_CONTROL_FILE_BYTES = 1_000_000


class ControlError(ValueError):
    """Controls that cannot be added; the message says why."""


def training_options(study: Study) -> DatasetOptions:
    """The dataset options every checkpoint system of the study was trained with."""
    systems = list(study.systems.exclude(checkpoint=""))
    if not systems:
        raise ControlError("register a model checkpoint first: controls follow the data and frame rate it was trained on")
    variants: dict[str, list[str]] = {}
    for system in systems:
        variants.setdefault(json.dumps(system.metadata["dataset_options"], sort_keys=True), []).append(system.name)
    if len(variants) > 1:
        groups = "; ".join(", ".join(names) for names in variants.values())
        raise ControlError(f"the study's checkpoints were trained on differently prepared data ({groups}); "
                           "one study needs one dataset")
    return DatasetOptions.from_dict(systems[0].metadata["dataset_options"])


def _save(study: Study, control: PathControl, origin: str, source_clip: str = "") -> ControlSignal:
    data = control.to_dict()
    existing = study.controls.filter(name=control.name).first()
    if existing is not None:
        if json.dumps(existing.control, sort_keys=True) != json.dumps(data, sort_keys=True):
            raise ControlError(f"this study already has a different control named {control.name!r}")
        return existing
    return ControlSignal.objects.create(study=study, name=control.name, origin=origin, control=data,
                                        source_clip=source_clip, seconds=control.n_frames / control.fps)


def _spread(controls: list[PathControl], contents: dict[str, str | None], count: int | None) -> list[PathControl]:
    """``count`` controls taking each content label in turn, so a short list still varies."""
    by_content: dict[str | None, list[PathControl]] = {}
    for control in controls:
        by_content.setdefault(contents[control.name], []).append(control)
    interleaved = [c for group in zip_longest(*by_content.values()) for c in group if c is not None]
    return interleaved[:count] if count else interleaved


def add_held_out_controls(study: Study, seconds: float, count: int | None = None) -> list[ControlSignal]:
    """Controls of the held-out clips of ``settings.MOTION_DATA`` cut to ``seconds`` (``count`` of them, or all)."""
    if not seconds > 0:
        raise ControlError(f"seconds must be positive, got {seconds}")
    options = training_options(study)
    folder = Path(settings.MOTION_DATA)
    try:
        dataset = build_dataset(folder, options, cache_dir=Path(settings.VAR_DIR) / "cache", progress=False)
    except (FileNotFoundError, ValueError) as error:
        raise ControlError(f"cannot read the motion data at {folder} (MOTION_DATA): {error}") from None
    trained_on = {s.metadata.get("data_fingerprint") for s in study.systems.exclude(checkpoint="")}
    if dataset.fingerprint not in trained_on:
        raise ControlError(f"the motion data at {folder} (MOTION_DATA) is not the data the checkpoints were trained on "
                           f"(fingerprint {dataset.fingerprint[:12]}, checkpoints {', '.join(sorted(f[:12] for f in trained_on))}); "
                           "its held-out clips could have been training clips")
    files = {path.stem: path for path in find_bvh_files(folder)}
    contents = {clip.name: clip.content for clip in dataset.select("test", augmented=False)}
    chosen = _spread(held_out_paths(dataset, seconds), contents, count)
    result = []
    for control in chosen:
        named = PathControl(control.velocities, control.fps, f"{control.name}-{seconds:g}s")
        result.append(_save(study, named, ControlSignal.Origin.HELD_OUT, str(files[control.name].relative_to(folder))))
    return result


def add_preset_controls(study: Study, names: list[str]) -> list[ControlSignal]:
    """Synthetic controls from ``generation.control.PRESETS`` by name."""
    fps = training_options(study).fps
    try:
        controls = [preset_path(name, fps) for name in names]
    except ValueError as error:
        raise ControlError(str(error)) from None
    return [_save(study, control, ControlSignal.Origin.SYNTHETIC) for control in controls]


def add_control_file(study: Study, upload: File) -> list[ControlSignal]:
    """Synthetic controls from an uploaded JSON or YAML description (one path or a list)."""
    name = Path(upload.name or "").name
    if Path(name).suffix.lower() not in CONTROL_FILE_SUFFIXES:
        raise ControlError(f"{name or 'the file'}: a control description must be {', '.join(CONTROL_FILE_SUFFIXES)}")
    if upload.size > MAX_CONTROL_FILE_BYTES:
        raise ControlError(f"{name}: {upload.size / 1e6:.1f} MB is over the {MAX_CONTROL_FILE_BYTES / 1e6:.0f} MB limit")
    fps = training_options(study).fps
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(b"".join(upload.chunks()))
        try:
            controls = load_control_file(path, fps)
        except (ValueError, UnicodeDecodeError) as error:
            raise ControlError(str(error).replace(str(path), name)) from None
    return [_save(study, control, ControlSignal.Origin.SYNTHETIC) for control in controls]


__all__ = ["ControlError", "add_control_file", "add_held_out_controls", "add_preset_controls", "training_options"]
