"""The shape of a study definition, shared by what writes one and what reads one.

The study's own settings are grouped as the study page groups them (``StudyForm.SECTIONS``,
a key per section: "Crowd platform" is ``crowd_platform``), each under its model field's
name, so a setting added to the study page appears in the definition by itself. The
camera is a mapping of ``Camera``'s fields in the video section. Questions, systems and
controls follow as lists; whether a study is open is not part of its definition (a study
made from one is closed until its researcher opens it).
"""

from __future__ import annotations

import dataclasses
import re
from typing import NamedTuple

from django.db import models

from generation.render.camera import Camera
from studyapp.models import Question, Study, System
from studyapp.researchers.setup.forms import QuestionForm, StudyForm

VERSION_KEY, VERSION = "version", 1
CAMERA_KEY = "camera"
LISTS = ("questions", "systems", "controls")
NOT_DEFINED = ("is_open",)  # the researcher opens a study; a definition never does
Number = (int, float)


def value_words(value: object) -> str:
    """What a YAML value is, in words ("a mapping", "a whole number")."""
    return {dict: "a mapping", list: "a list", str: "text", bool: "true/false", type(None): "empty",
            int: "a whole number", float: "a number"}.get(type(value), type(value).__name__)


def type_words(expected: type | tuple[type, ...]) -> str:
    """The values of a key's type, in words ("a number or empty")."""
    kinds = expected if isinstance(expected, tuple) else (expected,)
    if int in kinds and float in kinds:
        kinds = tuple(k for k in kinds if k is not int)
    return " or ".join("a number" if k is float else value_words(k()) if k is not type(None) else "empty" for k in kinds)


def section_key(title: str) -> str:
    return re.sub(r"\W+", "_", title.lower()).strip("_")


def study_sections() -> list[tuple[str, list[str]]]:
    """(section key, the Study fields in it) for every section of the study page, with the
    fields no section names in a last ``other_settings``."""
    defined = [name for name in StudyForm.base_fields if name not in NOT_DEFINED]
    sections = [(section_key(title), [name for name in names if name in defined]) for title, names in StudyForm.SECTIONS]
    placed = {name for _, names in sections for name in names}
    others = [name for name in defined if name not in placed]
    return sections + ([("other_settings", others)] if others else [])


def camera_section() -> str:
    """The section the camera's mapping is in: the one of the video's size."""
    return next(key for key, names in study_sections() if "video_width" in names)


def field_type(model: type[models.Model], name: str) -> type | tuple[type, ...]:
    """The YAML value type a model field takes: true/false, a whole number, a number or text,
    or empty where the field may be empty (null=True, as a plan's optional expected effect)."""
    field = model._meta.get_field(name)
    if isinstance(field, models.BooleanField):
        kind = (bool,)
    elif isinstance(field, models.IntegerField):
        kind = (int,)
    elif isinstance(field, models.FloatField):
        kind = Number
    else:
        kind = (str,)
    if not field.null:
        return kind if len(kind) > 1 else kind[0]
    return (*kind, type(None))


def camera_types() -> dict[str, type | tuple[type, ...]]:
    """Each camera field's type (None allowed where the field may be None)."""
    types = {}
    for spec in dataclasses.fields(Camera):
        kind = bool if spec.type in ("bool", bool) else Number
        types[spec.name] = (*((kind,) if kind is bool else kind), type(None)) if spec.default is None else kind
    return types


# A question's settings: QuestionForm's fields, choices and accepted answers as lists.
QUESTION_LISTS = ("choices", "accepted")
QUESTION_REQUIRED = ("part", "name", "text")


def question_types() -> dict[str, type | tuple[type, ...]]:
    return {name: list if name in QUESTION_LISTS else field_type(Question, name) for name in QuestionForm.Meta.fields}


class Key(NamedTuple):
    """One key of a system's or control's mapping in a definition: the YAML type of its value,
    what it says (docs/reference/study-file.md is written from these) and whether it must be given."""

    name: str
    type: type | tuple[type, ...]
    meaning: str
    required: bool = False


def types(keys: tuple[Key, ...]) -> dict[str, type | tuple[type, ...]]:
    return {key.name: key.type for key in keys}


def required(keys: tuple[Key, ...]) -> tuple[str, ...]:
    return tuple(key.name for key in keys if key.required)


# What each kind of system and control is written as, besides its name (and a system's role).
SYSTEM_SOURCES = ("checkpoint", "submitted", "videos")  # none of them: the natural clips
SYSTEM_KEYS = (
    Key("name", str, "the system's name, as the study's pages and its ratings table's `system` column name it", True),
    Key("role", str, "what the system is: " + ", ".join(f"`{role}` ({label})" for role, label in System.Role.choices),
        True),
    Key("checkpoint", dict, "a model checkpoint the study samples (its keys below)"),
    Key("submitted", dict, "motion generated elsewhere for the study's controls, already uploaded (its keys below)"),
    Key("videos", list, "a system of uploaded videos: their file names, for the record only (a definition cannot "
                        "make it; add its videos on the systems page)"),
    Key("temperature", Number, "a checkpoint's sampling temperature (default 1)"),
    Key("figure", dict, "corrections of the mapping of the system's rig to the display figure's body points: "
                        "`point: joint name` (the system's figure page shows the mapping)"),
)
CHECKPOINT_KEYS = (
    Key("digest", str, "the SHA-256 digest of the checkpoint file, which must be in the checkpoint store "
                       "(`CHECKPOINT_ROOT`)", True),
    Key("file", str, "the file name it was uploaded as", True),
    Key("kind", str, "its model kind (`moglow`, `rnn`, ...), as the checkpoint says"),
)
SUBMITTED_KEYS = (
    Key("digest", str, "the SHA-256 digest of its stored clips, which must be in the checkpoint store", True),
    Key("file", str, "the file name it was uploaded as"),
    Key("controls", list, "the names of the controls it has clips of"),
)
CONTROL_SOURCES = ("preset", "path", "labels", "held_out")
CONTROL_KEYS = (
    Key("name", str, "the control's name in the study", True),
    Key("export_id", str, "the name of its files for other labs (kept when the control was renamed)"),
    Key("preset", str, "a preset path by its name (the controls page lists them)"),
    Key("path", dict, "any other path, frame by frame (its keys below)"),
    Key("labels", dict, "a label control for label-controlled models (its keys below)"),
    Key("held_out", dict, "a clip of a held-out take of the motion data (its keys below)"),
)
PATH_KEYS = (
    Key("fps", Number, "frames per second", True),
    Key("velocities", list, "one frame a line: forward and sideways velocity in cm/s, turning in rad/s", True),
)
LABEL_KEYS = (
    Key("action", str, "the action label", True),
    Key("style", str, "the style label", True),
    Key("seconds", Number, "the clip's length", True),
)
HELD_OUT_KEYS = (
    Key("take", str, "the take's file name, read from `MOTION_DATA` or the folders named", True),
    Key("seconds", Number, "the clip's length (the take is cut to it)", True),
    Key("lead_in", Number, "seconds of the take before the clip, which path-controlled models warm up on and NAT "
                           "leaves out (default 0)"),
    Key("folders", list, "the folders to read the take from (default `MOTION_DATA`'s)"),
    Key("unit", Number, "a study without checkpoints: the take's unit, in centimetres per unit of the file "
                        "(checkpoints fix it)"),
    Key("up", str, "a study without checkpoints: the take's up axis (checkpoints fix it)"),
)


def study_types() -> dict[str, type | tuple[type, ...]]:
    return {name: field_type(Study, name) for _, names in study_sections() for name in names}
