"""What a study keeps fixed once it has begun, asked by every path that changes one.

Once a participant has started, what participants are shown and judged by is fixed: the
study's instrument (``INSTRUMENT`` and the camera), its systems, controls and questions,
which system, control and seed each clip is, and every page and rating participants were
given; changing any of it would mix answers to two instruments in one table. Anything
else a researcher changes in a locked study is allowed and recorded as a deviation from
its plan (``lock``'s signals); systems and controls may still be added, and are recorded
so. From the moment the plan is locked, clips drawn with another seed than the study's
clips are refused: the seed is no part of the plan, so a second set of clips could not be
recorded as a deviation.

The study pages (``StudyForm``'s fixed fields, the systems, controls and questions pages),
the admin (``studyapp.admin``) and the commands (``generate_stimuli`` through
``stimuli.clips.plan_stimuli``) all ask here.
"""

from __future__ import annotations

from collections.abc import Iterable

from django.db import models

from studyapp.models import (Assignment, ControlSignal, Participant, Question, Rating, Stimulus, Study, StudyPlan,
                             System)

# The study's settings that participants are shown and judged by (and the camera).
INSTRUMENT = ("design", "abx", "question", "scale_min", "scale_max", "label_min", "label_max", "preference_strengths",
              "bad_threshold", "natural_threshold", "video_width", "video_height", "sliders_must_move",
              "reasons", "reasons_required")
# The fields of each kind of row that are fixed once anyone has started (None: all of them).
FIXED_FIELDS: dict[type[models.Model], tuple[str, ...] | None] = {
    Study: (*INSTRUMENT, "camera"),
    System: None, ControlSignal: None, Question: None, Assignment: None, Rating: None,
    Stimulus: ("system", "control", "shown_control", "seed", "content_key"),
    # What the exclusions and the report read of a participant: the app records it as they answer.
    Participant: ("training", "training_done", "finished_at", "failed_checks", "stopped_at", "screened_at",
                  "screened_out_at", "answers", "excluded", "exclusion_reason", "refused_early"),
}
# Rows of these kinds may be added to a started study (and are recorded as deviations).
ADDED_LATER = (System, ControlSignal, Stimulus)
STARTED = "participants have started this study"


class StudyFixed(ValueError):
    """A change that a study which has begun does not allow; the message says what and why."""


def started(study: Study) -> bool:
    return study.participants.exists()


def study_of(row: models.Model) -> Study | None:
    """The study a row belongs to (None for a row not yet given one, and for a study not yet saved)."""
    if isinstance(row, Study):
        return row if row.pk is not None else None
    if isinstance(row, Rating):
        row = row.assignment if row.assignment_id else None
    if isinstance(row, Assignment):
        row = row.participant if row and row.participant_id else None
    return row.study if row is not None and row.study_id else None


def _what(row: models.Model) -> str:
    return f"{row._meta.verbose_name} {getattr(row, 'name', '') or row.pk or ''}".strip()


def change_refusal(row: models.Model, changed: Iterable[str]) -> str | None:
    """Why changing the fields ``changed`` of ``row`` (a new row: adding it) is refused, or None."""
    study = study_of(row)
    if study is None or type(row) not in FIXED_FIELDS:
        return None
    if row.pk is None and isinstance(row, Stimulus) and (refusal := seed_refusal(study, row.seed)):
        return refusal
    if not started(study):
        return None
    if row.pk is None:
        return None if isinstance(row, ADDED_LATER) else f"{STARTED}: no {row._meta.verbose_name} can be added"
    fixed = FIXED_FIELDS[type(row)]
    refused = [name for name in changed if fixed is None or name in fixed]
    if not refused:
        return None
    return f"{STARTED}: {_what(row)}'s {', '.join(name.replace('_', ' ') for name in refused)} cannot change"


def deletion_refusal(row: models.Model) -> str | None:
    """Why deleting ``row`` is refused, or None (a whole study may always be deleted, with its data)."""
    study = study_of(row)
    if isinstance(row, Study) or study is None or type(row) not in FIXED_FIELDS or not started(study):
        return None
    return f"{STARTED}: {_what(row)} cannot be removed"


def seed_refusal(study: Study, seed: int) -> str | None:
    """Why clips drawn with ``seed`` are refused (a second set in a study whose plan is locked), or None."""
    if not StudyPlan.objects.filter(study=study).exists():
        return None
    seeds = sorted(set(study.stimuli.exclude(seed=seed).values_list("seed", flat=True)))
    if not seeds:
        return None
    return (f"the plan of this study is locked with its clips drawn with seed {seeds[0]}: clips of seed {seed} would "
            "be a second set, which participants would rate as the same clips")


def require_seed_allowed(study: Study, seed: int) -> None:
    """StudyFixed where ``seed_refusal`` refuses the seed."""
    if (refusal := seed_refusal(study, seed)) is not None:
        raise StudyFixed(refusal)


__all__ = ["FIXED_FIELDS", "INSTRUMENT", "STARTED", "StudyFixed", "change_refusal", "deletion_refusal",
           "require_seed_allowed", "seed_refusal", "started", "study_of"]
