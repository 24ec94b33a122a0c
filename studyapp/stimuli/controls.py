"""Choosing a study's control signals: held out from the motion data, or synthetic.

A study's checkpoints decide the kind of control: a path (MoGlow and its baselines) or an
action and a style label (HVRNN, ERD, QuaterNet); one study holds one kind, since it
holds models trained on one dataset. A study without checkpoints (submitted motion and
NAT only) is controlled by paths.

Held-out controls come from real takes, which the NAT system shows. In a study with
checkpoints they are the test split of the very dataset the checkpoints were trained on
(same files, same options, so the same split; the data's fingerprint is checked): the
models never saw these clips. A study without checkpoints takes them from any folder,
no model trained on it: the takes that the seeded split ``train`` makes of the folder
holds out (``generation.motion.takes``), read in the unit and up axis detected from the
files or given. In either, the researcher may name the takes instead (with checkpoints,
only takes they held out). A held-out path is the clip's own path; a held-out label
control is the clip's action and style. Synthetic controls are ``generation.control``'s
path presets or a JSON/YAML description, or chosen pairs of labels. All follow the frame
rate of the study's motion (``study_options``). Adding a control again is harmless;
adding a different control under a taken name is refused.
"""

from __future__ import annotations

import dataclasses
import json
from itertools import zip_longest
from pathlib import Path

from django.conf import settings
from django.core.files import File

from generation.control import (AttributeControl, Control, PathControl, described_paths, held_out_attributes,
                                held_out_paths, lead_in_frames, preset_path, shorter_than_asked, take_paths)
from generation import registry
from generation.motion.clip_files import LOCOMOTION, contents_or_all, find_bvh_files, motion_folders
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.motion.takes import natural_takes
from studyapp.models import ControlSignal, Study
from studyapp.server.uploads.bounded_reading import json_value, yaml_value
from studyapp.stimuli.natural import data_folders, natural_source, source_name

CONTROL_FILE_SUFFIXES = (".json", ".yaml", ".yml")
MAX_CONTROL_FILE_BYTES = 1_000_000


class ControlError(ValueError):
    """Controls that cannot be added; the message says why."""


def training_options(study: Study) -> DatasetOptions:
    """The dataset options every checkpoint system of the study was trained with."""
    systems = list(study.systems.exclude(checkpoint=""))
    if not systems:
        raise ControlError("register a model checkpoint first: controls follow the data and frame rate it was trained on")
    variants: dict[DatasetOptions, list[str]] = {}
    for system in systems:
        variants.setdefault(system.dataset_options(), []).append(system.name)
    if len(variants) > 1:
        groups = "; ".join(", ".join(names) for names in variants.values())
        raise ControlError(f"the study's checkpoints were trained on differently prepared data ({groups}); "
                           "one study needs one dataset")
    return next(iter(variants))


def study_options(study: Study) -> DatasetOptions:
    """How the study's motion is read (its frame rate and where a body's root is): the
    options its checkpoints were trained with; in a study without checkpoints, those
    its first held-out takes were read with, else the defaults (20 fps)."""
    if study.systems.exclude(checkpoint="").exists():
        return training_options(study)
    recorded = next((options for c in study.controls.exclude(source_clip="") if (options := c.recorded_options())), None)
    return recorded or DatasetOptions()


def natural_options(control: ControlSignal) -> DatasetOptions:
    """The dataset options a held-out control's take is read with: those recorded when
    it was added (controls added before they were recorded: the checkpoints')."""
    return control.recorded_options() or training_options(control.study)


def control_kind(study: Study) -> str:
    """What the study's checkpoints are controlled by, as the model registry says:
    ``registry.PATH`` or ``registry.LABELS`` (a study without checkpoints takes paths)."""
    kinds = set()
    for system in study.systems.exclude(checkpoint=""):
        if system.kind not in registry.MODELS:
            raise ControlError(f"{system.name} is a {system.kind!r} model, a kind this server does not know "
                               f"(known: {', '.join(registry.MODELS)})")
        kinds.add(registry.MODELS[system.kind].control)
    if len(kinds) > 1:  # training_options refuses such a study too; say it in these words
        raise ControlError("the study mixes path-controlled and label-controlled models; one study needs one kind")
    return kinds.pop() if kinds else registry.PATH


def study_labels(study: Study) -> tuple[list[str], list[str]]:
    """The actions and styles every label-controlled system of the study knows."""
    labels = [found for s in study.systems.exclude(checkpoint="") if (found := s.labels())]
    if not labels:
        return [], []
    known = [labels[0][kind] for kind in ("actions", "styles")]
    for other in labels[1:]:
        known = [[name for name in names if name in other[kind]] for names, kind in zip(known, ("actions", "styles"))]
    return known[0], known[1]


def _require(study: Study, kind: str) -> None:
    if control_kind(study) != kind:
        raise ControlError("this study's models follow a path: add held-out or synthetic paths" if kind == registry.LABELS
                           else "this study's models are controlled by action and style labels: add held-out or "
                                "chosen label pairs, not paths")


def _save(study: Study, control: Control, origin: str, source_clip: str = "", natural: dict | None = None
          ) -> ControlSignal:
    data = control.to_dict()
    existing = study.controls.filter(name=control.name).first()
    if existing is not None:
        if json.dumps(existing.control, sort_keys=True) != json.dumps(data, sort_keys=True):
            raise ControlError(f"this study already has a different control named {control.name!r}")
        return existing
    return ControlSignal.objects.create(study=study, name=control.name, origin=origin, control=data,
                                        source_clip=source_clip, natural=natural or {},
                                        seconds=control.n_frames / control.fps)


def _spread(controls: list[Control], contents: dict[str, str | None], count: int | None) -> list[Control]:
    """``count`` controls taking each content label in turn, so a short list still varies;
    the longest come first (and so do their labels). The controls are already cut to the
    clip's length, so a count gives whole clips where the data has them."""
    by_content: dict[str | None, list[Control]] = {}
    for control in sorted(controls, key=lambda c: -c.n_frames):  # stable: dataset order among equals
        by_content.setdefault(contents[control.name], []).append(control)
    interleaved = [c for group in zip_longest(*by_content.values()) for c in group if c is not None]
    return interleaved[:count] if count else interleaved


def add_held_out_controls(study: Study, seconds: float, count: int | None = None, lead_in: float = 0.0,
                          folders: list[str] | None = None, takes: list[str] | None = None,
                          scale: float | None = None, up: str | None = None) -> list[ControlSignal]:
    """Controls of held-out takes cut to ``seconds`` (``count`` of them, or all), of the
    ``folders`` (default: ``settings.MOTION_DATA``).

    The takes are the held-out ones of the seeded split, or those ``takes`` names (file
    names without .bvh). With checkpoints in the study, the folders must be the data
    they were trained on, read with their options; without, the study's motion is read
    at 20 fps in the unit and up axis detected from the files, unless ``scale`` (file
    units to cm) and ``up`` are given.

    With a ``lead_in`` (path controls only) each clip starts that many seconds into its
    take, the models warm up on the take's control before it, and NAT shows the same
    frames: the MoGlow authors sample a test take from its first frame, and a walk's first
    second is often slower than the rest of it.
    """
    if not seconds > 0:
        raise ControlError(f"seconds must be positive, got {seconds}")
    kind = control_kind(study)
    if lead_in and kind != registry.PATH:
        raise ControlError("a lead-in is the path before the clip: this study's models are controlled by labels")
    trained = study.systems.exclude(checkpoint="").exists()
    if trained and (scale is not None or up is not None):
        raise ControlError("the study's checkpoints fix the unit and up axis their data is read in; a unit or an "
                           "up axis is for the takes of a study without checkpoints")
    options = training_options(study) if trained else DatasetOptions(scale=scale, up=up)
    try:
        lead = lead_in_frames(lead_in, options.fps) / options.fps  # refused before the data is read
    except ValueError as error:
        raise ControlError(str(error)) from None
    where = " ".join(map(str, folders)) if folders else f"{settings.MOTION_DATA} (MOTION_DATA)"
    wanted = [Path(name).stem if name.lower().endswith(".bvh") else name for name in takes or []]
    try:
        folders = motion_folders(folders) if folders else data_folders()
        if trained:
            held_out, contents = _trained_takes(study, folders, options, kind, wanted, seconds, lead, where)
        else:
            held_out, contents, options = _untrained_takes(folders, options, wanted, seconds, lead)
    except ControlError:
        raise
    except (FileNotFoundError, ValueError) as error:
        raise ControlError(f"cannot read the motion data at {where}: {error}") from None
    if lead and not held_out:
        raise ControlError(f"no held-out take of {where} is longer than the lead-in of {lead:g} s")
    files = {path.stem: path for path in find_bvh_files(folders)}
    source = natural_source(folders, options)
    result = []
    short = {control.name for control in shorter_than_asked(held_out, seconds)}
    for control in _spread(held_out, contents, count):
        # Named by the length it has: a take that ends sooner gives a shorter clip than asked.
        length = f"{round(control.n_frames / control.fps, 2):g}" if control.name in short else f"{seconds:g}"
        cut = f"{lead:g}s+{length}s" if lead else f"{length}s"
        named = dataclasses.replace(control, name=f"{control.name}-{cut}")
        result.append(_save(study, named, ControlSignal.Origin.HELD_OUT, source_name(files[control.name], folders),
                            source))
    return result


def shorter_than_asked_warnings(controls: list[ControlSignal], seconds: float) -> list[str]:
    """A warning for each of ``controls`` (as ``add_held_out_controls`` returns them) that
    lasts less than the ``seconds`` asked, its take ending sooner: the page and the command
    line say so, and its name gives its real length."""
    return [f"{control.name} lasts {control.seconds:.2f} s, not the {seconds:g} s asked: its take ends sooner"
            for control in controls
            if round(control.seconds * control.control["fps"]) < round(seconds * control.control["fps"])]


def _trained_takes(study: Study, folders: list[Path], options: DatasetOptions, kind: str, wanted: list[str],
                   seconds: float, lead: float, where: str) -> tuple[list[Control], dict[str, str | None]]:
    """The held-out controls of the data the study's checkpoints were trained on, and
    each take's content; ControlError where the folders are other data or a named take
    was not held out."""
    dataset = build_dataset(folders, options, cache_dir=Path(settings.VAR_DIR) / "cache", progress=False)
    trained_on = {s.metadata.get("data_fingerprint") for s in study.systems.exclude(checkpoint="")}
    if dataset.fingerprint not in trained_on:
        raise ControlError(f"the motion data at {where} is not the data the checkpoints were trained on "
                           f"(fingerprint {dataset.fingerprint[:12]}, checkpoints {', '.join(sorted(f[:12] for f in trained_on))}); "
                           "its held-out clips could have been training clips")
    contents = {clip.name: clip.content for clip in dataset.select("test", augmented=False)}
    trained_takes = [name for name in wanted if name not in contents]
    if trained_takes:
        raise ControlError(f"the study's checkpoints may have been trained on {', '.join(trained_takes)}: named "
                           f"takes must be among the takes held out of their data ({', '.join(sorted(contents))})")
    if kind == registry.PATH:
        held_out = held_out_paths(dataset, seconds, lead)
    else:  # only what every model of the study can be asked for
        actions, styles = study_labels(study)
        held_out = [c for c in held_out_attributes(dataset, seconds) if c.action in actions and c.style in styles]
    return [c for c in held_out if not wanted or c.name in wanted], contents


def _untrained_takes(folders: list[Path], options: DatasetOptions, wanted: list[str], seconds: float, lead: float
                     ) -> tuple[list[Control], dict[str, str | None], DatasetOptions]:
    """The held-out paths of takes no checkpoint of the study was trained on: those the
    seeded split that training on the folders makes holds out (of the locomotion contents
    where the takes have labels, as ``train`` takes them), or the ``wanted`` ones; each
    take's content; and the options with the unit and up axis as read."""
    options = dataclasses.replace(options, contents=None if wanted else contents_or_all(folders, LOCOMOTION))
    found, options = natural_takes(folders, options, wanted or None)
    held_out = take_paths([(take.name, take.control) for take in found], options.fps, seconds, lead)
    return held_out, {take.name: take.content for take in found}, options


def add_label_controls(study: Study, actions: list[str], styles: list[str], seconds: float) -> list[ControlSignal]:
    """Synthetic label controls: every chosen action with every chosen style, ``seconds`` long."""
    _require(study, registry.LABELS)
    known_actions, known_styles = study_labels(study)
    for names, known, kind in ((actions, known_actions, "action"), (styles, known_styles, "style")):
        if not names:
            raise ControlError(f"choose at least one {kind}")
        unknown = [name for name in names if name not in known]
        if unknown:
            raise ControlError(f"not every model knows the {kind}(s) {', '.join(unknown)}")
    if not seconds > 0:
        raise ControlError(f"seconds must be positive, got {seconds}")
    fps = training_options(study).fps
    frames = int(round(seconds * fps))
    return [_save(study, AttributeControl(action, style, frames, fps, f"{action}-{style}-{seconds:g}s"),
                  ControlSignal.Origin.SYNTHETIC) for action in actions for style in styles]


def add_preset_controls(study: Study, names: list[str]) -> list[ControlSignal]:
    """Synthetic controls from ``generation.control.PRESETS`` by name."""
    _require(study, registry.PATH)
    fps = study_options(study).fps
    try:
        controls = [preset_path(name, fps) for name in names]
    except ValueError as error:
        raise ControlError(str(error)) from None
    return [_save(study, control, ControlSignal.Origin.SYNTHETIC) for control in controls]


def add_path_control(study: Study, control: PathControl) -> ControlSignal:
    """A synthetic path given frame by frame (a study definition's custom path), at the
    frame rate of the study's motion."""
    _require(study, registry.PATH)
    fps = study_options(study).fps
    if abs(control.fps - fps) > 1e-9:
        raise ControlError(f"the path is at {control.fps:g} fps and the study's motion at {fps:g} fps")
    return _save(study, control, ControlSignal.Origin.SYNTHETIC)


def add_control_file(study: Study, upload: File) -> list[ControlSignal]:
    """Synthetic controls from an uploaded JSON or YAML description (one path or a list)."""
    name = Path(upload.name or "").name
    if Path(name).suffix.lower() not in CONTROL_FILE_SUFFIXES:
        raise ControlError(f"{name or 'the file'}: a control description must be {', '.join(CONTROL_FILE_SUFFIXES)}")
    if upload.size > MAX_CONTROL_FILE_BYTES:
        raise ControlError(f"{name}: {upload.size / 1e6:.1f} MB is over the {MAX_CONTROL_FILE_BYTES / 1e6:.0f} MB limit")
    _require(study, registry.PATH)
    fps = study_options(study).fps
    data = upload.read(MAX_CONTROL_FILE_BYTES + 1)  # a file larger than it said: still never more than the limit
    read = yaml_value if Path(name).suffix.lower() in (".yaml", ".yml") else json_value
    try:
        controls = described_paths(read(data, name, MAX_CONTROL_FILE_BYTES), name, Path(name).stem, fps)
    except ValueError as error:  # ReadRefused too
        raise ControlError(str(error)) from None
    return [_save(study, control, ControlSignal.Origin.SYNTHETIC) for control in controls]


__all__ = ["ControlError", "add_control_file", "add_held_out_controls", "add_label_controls", "add_path_control",
           "add_preset_controls", "control_kind", "natural_options", "shorter_than_asked_warnings", "study_labels",
           "study_options", "training_options"]
