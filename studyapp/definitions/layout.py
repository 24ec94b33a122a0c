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

from django.db import models

from generation.render.camera import Camera
from studyapp.models import Question, Study
from studyapp.researchers.setup.forms import QuestionForm, StudyForm

VERSION_KEY, VERSION = "version", 1
CAMERA_KEY = "camera"
LISTS = ("questions", "systems", "controls")
NOT_DEFINED = ("is_open",)  # the researcher opens a study; a definition never does
Number = (int, float)


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


def question_types() -> dict[str, type | tuple[type, ...]]:
    return {name: list if name in QUESTION_LISTS else field_type(Question, name) for name in QuestionForm.Meta.fields}


# What each kind of system and control is written as, besides its name (and a system's role).
SYSTEM_SOURCES = ("checkpoint", "submitted", "videos")  # none of them: the natural clips
CHECKPOINT_KEYS = {"digest": str, "file": str, "kind": str}
SUBMITTED_KEYS = {"digest": str, "file": str, "controls": list}  # the controls it has clips of
CONTROL_SOURCES = {
    "preset": str,
    "path": dict,  # fps and the velocities, frame by frame
    "labels": dict,  # action, style, seconds
    "held_out": dict,  # take, seconds, lead_in and where the take was found and how it was read
}
PATH_KEYS = {"fps": Number, "velocities": list}
LABEL_KEYS = {"action": str, "style": str, "seconds": Number}
HELD_OUT_KEYS = {"take": str, "seconds": Number, "lead_in": Number, "folders": list, "unit": Number, "up": str}


def study_types() -> dict[str, type | tuple[type, ...]]:
    return {name: field_type(Study, name) for _, names in study_sections() for name in names}
