"""Writing a study as its definition: every setting, question, system and control, as
``create_study_from_definition`` reads them back (``layout`` says where each goes).

A system is written by where its motion comes from: a checkpoint by its digest in the
checkpoint store and the file name it was uploaded as, submitted motion by the digest of
its stored clips, NAT by its role alone; a system of uploaded videos by their names, for
the record only (a definition holds no videos, so ``create_study --from`` refuses it and
says to add it on the systems page; a study bundle carries them). A control is written
by how it is made again: a preset by name, a held-out control by its take, length and
lead-in, a label control by its action, style and length, any other path by its
velocities frame by frame. Its export id (the name other labs' files carry) is kept. A held-out take found in the
folders of ``MOTION_DATA`` is named without them: created on another server, the
definition reads the take from that server's ``MOTION_DATA``.
"""

from __future__ import annotations

import enum
from pathlib import Path

import yaml

from generation.control import PRESETS, AttributeControl, PathControl, preset_path
from generation.render.camera import Camera
from studyapp.definitions import layout
from studyapp.models import ControlSignal, Question, StoredDataError, Study, System, json_object
from studyapp.stimuli.natural import data_folders


def _plain(value: object) -> object:
    """A stored value as YAML writes it: a choice as its text (a row just made holds the enum)."""
    return value.value if isinstance(value, enum.Enum) else value


def _question(question: Question) -> dict:
    entry = {"part": _plain(question.part), "name": question.name, "text": question.text, "kind": _plain(question.kind)}
    if question.kind == Question.Kind.CHOICE:
        entry |= {"choices": question.choice_list, "accepted": question.accepted_list}
    entry["required"] = question.required
    if question.kind == Question.Kind.NUMBER:
        entry |= {"minimum": question.minimum, "maximum": question.maximum, "whole_numbers": question.whole_numbers}
    return entry


def _system(system: System) -> dict:
    entry: dict = {"name": system.name, "role": _plain(system.role)}
    metadata = system.metadata if isinstance(system.metadata, dict) else {}
    kind = system.source_kind
    if kind == System.SourceKind.CHECKPOINT:
        entry["checkpoint"] = {"digest": system.checkpoint_digest,
                               "file": metadata.get("file") or Path(system.checkpoint).name, "kind": system.kind}
        entry["temperature"] = system.temperature
    elif kind == System.SourceKind.SUBMITTED:
        entry["submitted"] = {"digest": system.checkpoint_digest, "file": metadata.get("file", ""),
                              "controls": list(metadata.get("controls", []))}
    elif kind == System.SourceKind.VIDEO:
        entry["videos"] = list(metadata.get("videos", []))
    if system.figure_mapping:  # the researcher's corrections of its rig's mapping to the display figure
        entry["figure"] = dict(system.figure_mapping)
    return entry


def _preset_of(signal: PathControl) -> str | None:
    """The preset whose path ``signal`` is, at its frame rate (None if it is none)."""
    for name in PRESETS:
        preset = preset_path(name, signal.fps)
        if preset.n_frames == signal.n_frames and signal.lead_in is None \
                and preset.to_dict()["velocities"] == signal.to_dict()["velocities"]:
            return name
    return None


def _control(control: ControlSignal, trained: bool) -> dict:
    entry: dict = {"name": control.name, "export_id": control.export_id}
    signal = control.signal()
    if control.origin == ControlSignal.Origin.HELD_OUT:
        held_out = {"take": control.source_clip, "seconds": control.seconds, "lead_in": control.lead_in_seconds}
        if control.natural:
            folders = json_object(control, "natural").get("folders", [])
            if not isinstance(folders, list) or not all(isinstance(folder, str) for folder in folders):
                raise StoredDataError(control, "natural", "holds folders that are no list of paths")
            if folders != [str(folder.absolute()) for folder in data_folders()]:  # else MOTION_DATA's, wherever it is
                held_out["folders"] = folders
            if not trained:  # checkpoints fix how their data is read; other takes were read in this unit and axis
                options = control.recorded_options()
                held_out |= {"unit": options.scale, "up": options.up}
        entry["held_out"] = held_out
    elif isinstance(signal, AttributeControl):
        entry["labels"] = {"action": signal.action, "style": signal.style, "seconds": signal.n_frames / signal.fps}
    elif (preset := _preset_of(signal)) is not None:
        entry["preset"] = preset
    else:
        entry["path"] = {"fps": signal.fps, "velocities": signal.to_dict()["velocities"]}
    return entry


def describe_study(study: Study) -> dict:
    """The study's definition as plain values (StoredDataError where a stored control or
    system cannot be read)."""
    definition: dict = {layout.VERSION_KEY: layout.VERSION}
    for key, names in layout.study_sections():
        definition[key] = {name: _plain(getattr(study, name)) for name in names}
    stored = study.camera if isinstance(study.camera, dict) else {}
    definition[layout.camera_section()][layout.CAMERA_KEY] = {**Camera().to_dict(), **stored}
    definition["questions"] = [_question(q) for q in study.questions.order_by("part", "order", "created", "pk")]
    definition["systems"] = [_system(s) for s in study.systems.order_by("role", "name")]
    trained = study.systems.exclude(checkpoint="").exists()
    definition["controls"] = [_control(c, trained) for c in study.controls.order_by("origin", "name")]
    return definition


class _Dumper(yaml.SafeDumper):
    """Text of several lines as a block, and a list of numbers (a frame of a path) on one line."""


def _text(dumper: yaml.SafeDumper, text: str) -> yaml.Node:
    text = text.replace("\r\n", "\n")  # a browser's line ends, as the text reads: a block, not "\r\n" escapes
    return dumper.represent_scalar("tag:yaml.org,2002:str", text, style="|" if "\n" in text else None)


def _list(dumper: yaml.SafeDumper, items: list) -> yaml.Node:
    numbers = items and all(isinstance(i, int | float) and not isinstance(i, bool) for i in items)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", items, flow_style=bool(numbers))


_Dumper.add_representer(str, _text)
_Dumper.add_representer(list, _list)


def definition_yaml(study: Study) -> str:
    """The study's definition as YAML text, with a first line that says what it is and how to use it."""
    body = yaml.dump(describe_study(study), Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=100)
    return f"# A study definition: python manage.py create_study USERNAME --from FILE makes it again.\n{body}"
