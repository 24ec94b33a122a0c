"""A study's rows as JSON records, and where each kind of file lies in a bundle.

Records keep every stored value a re-created study needs, so that the content keys of its
stimuli and its ratings table come out as the original's: the study's settings, its
systems, controls (with the exact control arrays and export ids) and questions
(``study.json``); its stimuli (``stimuli.json``); its participants with their pages and
answers (``participants.json``). Rows refer to each other by name (systems, controls)
or by token (stimuli), never by database id. Left out: database ids, the owner, the
study's key and open state, and what could identify a participant (their user agent,
and their platform values, which ``pseudonyms`` replaces).
"""

from __future__ import annotations

import json
from datetime import datetime

from django.db import models
from django.utils.dateparse import parse_datetime

from studyapp.models import Assignment, ControlSignal, Participant, Question, Rating, Stimulus, Study, System

STUDY_FILE, STIMULI_FILE, PARTICIPANTS_FILE = "study.json", "stimuli.json", "participants.json"
DEFINITION_FILE = "study.yaml"
RATINGS_FILE, RULES_FILE = "ratings.csv", "rules.json"
PLAN_FILE = "plan.json"  # the plan locked when the study opened, and its deviations (studyapp.preregistration)
RECORD_FILES = (STUDY_FILE, STIMULI_FILE, PARTICIPANTS_FILE, RULES_FILE, PLAN_FILE)  # JSON, read whole
CHECKPOINTS, MOTION, SAMPLED, VIDEOS, CONTROLS = "checkpoints/", "motion/", "sampled/", "stimuli/", "controls/"

# Fields a record never carries: ids and links (written as names or tokens), and what
# belongs to the database the study lives in or could identify a person.
LEFT_OUT = {
    Study: {"id", "owner", "key", "is_open", "previewed_at", "created", "updated"},
    System: {"id", "study", "created"},
    ControlSignal: {"id", "study"},
    Question: {"id", "study", "created"},
    Stimulus: {"id", "study", "system", "control", "shown_control", "status", "error", "attempts", "task_id",
               "updated"},
    Participant: {"id", "study", "user_agent", "training"},
    Assignment: {"id", "participant", "stimulus"},
    Rating: {"id", "assignment"},
}


def recorded_fields(model: type[models.Model]) -> list[models.Field]:
    return [field for field in model._meta.concrete_fields if field.name not in LEFT_OUT[model]]


def record(row: models.Model) -> dict:
    """The row's recorded fields as JSON values (times in ISO 8601, to the microsecond)."""
    values = {}
    for field in recorded_fields(type(row)):
        value = getattr(row, field.attname)
        values[field.name] = value.isoformat() if isinstance(value, datetime) else value
    return values


class RecordError(ValueError):
    """A record that makes no row; the message names the field."""


def row_values(model: type[models.Model], data: object, where: str) -> dict:
    """The field values of a record of ``model`` (RecordError naming ``where`` and the field
    if it has a field the model does not record, or a value not of the field's type)."""
    if not isinstance(data, dict):
        raise RecordError(f"{where}: expected an object of fields, got {type(data).__name__}")
    fields = {field.name: field for field in recorded_fields(model)}
    if unknown := sorted(set(data) - set(fields)):
        raise RecordError(f"{where}: unknown field(s) {', '.join(map(repr, unknown))}")
    return {name: _field_value(fields[name], value, f"{where}: {name}") for name, value in data.items()}


def _shown(value: object) -> str:
    return json.dumps(value, ensure_ascii=False)[:80]


def _field_value(field: models.Field, value: object, where: str) -> object:
    """``value`` as the field stores it, of exactly the JSON type the field's values have.

    Django's fields convert what they are given (``int(4.7)`` is 4, ``int(True)`` 1, and
    ``int("+3")``, ``int("٣")`` and ``int("３")`` are 3), which turns a wrong record into
    another right-looking one; here a record's value is taken only as export_study writes
    it, and the model's own validators (its bounds, the length of a text) check it after."""
    if value is None or isinstance(field, models.JSONField):
        return value
    if isinstance(field, models.DateTimeField):
        try:
            parsed = parse_datetime(value) if isinstance(value, str) else None
        except ValueError:  # the form of a time, but no time (February 30th, 25 o'clock)
            parsed = None
        if parsed is None:
            raise RecordError(f"{where} must be an ISO 8601 time, got {_shown(value)}")
        return parsed
    if isinstance(field, models.BooleanField):
        expected, kind = type(value) is bool, "true or false"
    elif isinstance(field, models.IntegerField):
        expected, kind = type(value) is int, "a whole number"
    elif isinstance(field, models.FloatField):
        expected, kind = type(value) in (int, float), "a number"
    else:
        expected, kind = isinstance(value, str), "text"
    if not expected:
        raise RecordError(f"{where} must be {kind}, not {_shown(value)}")
    if isinstance(value, str) and "\0" in value:
        raise RecordError(f"{where}: the text holds a NUL character (\\0), which no database stores")
    return value


def auto_stamped(model: type[models.Model]) -> list[str]:
    """The recorded fields Django stamps with the time a row is saved, which an import sets afterwards."""
    return [field.name for field in recorded_fields(model)
            if getattr(field, "auto_now_add", False) or getattr(field, "auto_now", False)]


__all__ = ["CHECKPOINTS", "CONTROLS", "DEFINITION_FILE", "MOTION", "PARTICIPANTS_FILE", "PLAN_FILE", "RATINGS_FILE",
           "RECORD_FILES", "RULES_FILE", "RecordError", "SAMPLED", "STIMULI_FILE", "STUDY_FILE", "VIDEOS",
           "auto_stamped", "record", "recorded_fields", "row_values"]
