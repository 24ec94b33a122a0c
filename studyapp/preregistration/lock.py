"""Locking a study's plan when it first opens, and recording every change made after.

The lock is a ``StudyPlan`` row: the plan (``contents.plan_contents`` with
``participants.planned_participants``) as canonical JSON, its SHA-256 and the time,
written once; a study opened again after closing keeps it.

Deviations are a log (``PlanDeviation`` rows), not a difference computed when the plan
is read: a difference shows only where things stand, not when each change was made,
and a change made and undone would vanish from it. Each save of a locked study, and
each save or deletion of one of its systems or controls, compares the plan as it now
stands (``contents.tracked``) with the locked plan updated by the deviations recorded so
far, and records each part that differs, with its old and new value. One comparison in
one place serves every path that changes a study (its pages, the commands, the admin,
the demo), as Django's signals reach them all; a study never opened records nothing.

The participants past the planned number are the one deviation not logged: the
participants' own rows already say when each finished, so ``deviations`` counts them
when asked, dated by the first participant past the plan.
"""

from __future__ import annotations

import hashlib
import json

from django.db import IntegrityError, transaction
from django.db.models.signals import post_delete, post_save
from django.utils import timezone

from studyapp.models import ControlSignal, PlanDeviation, Study, StudyPlan, System
from studyapp.preregistration.contents import canonical_json, plan_contents, tracked
from studyapp.preregistration.participants import planned_participants

PLAN_FORMAT = 1  # the plan's layout; a reader of an older one knows it by this
PARTICIPANTS = "participants"  # the deviation of more participants than planned


def build_plan(study: Study) -> dict:
    """The study's whole plan as it stands now (plain JSON data)."""
    return {"format": PLAN_FORMAT, **plan_contents(study), "participants": planned_participants(study)}


def lock_plan(study: Study) -> StudyPlan:
    """The study's locked plan: written now if it has none (two requests opening it at once write one)."""
    existing = StudyPlan.objects.filter(study=study).first()
    if existing is not None:
        return existing
    canonical = canonical_json(build_plan(study))
    try:
        with transaction.atomic():
            return StudyPlan.objects.create(study=study, canonical=canonical, locked_at=timezone.now(),
                                            sha256=hashlib.sha256(canonical.encode()).hexdigest())
    except IntegrityError:  # another request locked it first: theirs stands
        return StudyPlan.objects.get(study=study)


def _recorded_parts(plan: StudyPlan) -> dict[str, object]:
    """The tracked parts of the locked plan with every recorded deviation applied, in order."""
    parts = tracked(json.loads(plan.canonical))
    for deviation in PlanDeviation.objects.filter(study_id=plan.study_id).order_by("at", "pk"):
        parts[deviation.field] = deviation.new
    return parts


def record_deviations(study: Study) -> list[PlanDeviation]:
    """Record how the study's plan now differs from its locked plan and the deviations
    recorded so far (nothing for a study without a locked plan); the new deviations."""
    with transaction.atomic():
        plan = StudyPlan.objects.select_for_update().filter(study=study).first()
        if plan is None:
            return []
        before = _recorded_parts(plan)
        now = json.loads(canonical_json(tracked(plan_contents(study))))  # as the plan stores values
        at = timezone.now()
        changes = [PlanDeviation(study=study, at=at, field=field, old=before.get(field), new=now.get(field))
                   for field in sorted(before.keys() | now.keys()) if before.get(field) != now.get(field)]
        return PlanDeviation.objects.bulk_create(changes)


def _participants_past_plan(study: Study, plan: dict) -> dict | None:
    """More participants finished than planned: when the first past the plan finished, the
    planned and the present number (screened-out participants are not counted)."""
    planned = plan[PARTICIPANTS]["planned"]
    if planned is None:
        return None
    finished = study.participants.filter(finished_at__isnull=False, screened_out_at__isnull=True)
    count = finished.count()
    if count <= planned:
        return None
    first_past = finished.order_by("finished_at", "pk").values_list("finished_at", flat=True)[planned]
    return {"at": first_past.isoformat(), "field": PARTICIPANTS, "old": planned, "new": count, "recorded": False}


def frozen_plan(study: Study) -> dict | None:
    """The locked plan with its SHA-256 and lock time (ISO 8601); None for a study never opened.
    ``canonical_json(result["plan"])`` is the text the hash was taken of."""
    plan = StudyPlan.objects.filter(study=study).first()
    if plan is None:
        return None
    return {"plan": json.loads(plan.canonical), "sha256": plan.sha256, "locked_at": plan.locked_at.isoformat()}


def deviations(study: Study) -> list[dict]:
    """Every deviation from the locked plan in time order, each ``at`` (ISO 8601), ``field``,
    ``old``, ``new`` and ``recorded`` (false for the participants past the plan, which
    are counted from the participants' rows); empty for a study never opened."""
    plan = StudyPlan.objects.filter(study=study).first()
    if plan is None:
        return []
    rows = [{"at": row.at.isoformat(), "field": row.field, "old": row.old, "new": row.new, "recorded": True}
            for row in PlanDeviation.objects.filter(study=study).order_by("at", "pk")]
    past = _participants_past_plan(study, json.loads(plan.canonical))
    return sorted([*rows, past] if past else rows, key=lambda row: row["at"])


def preregistration(study: Study) -> dict:
    """The locked plan and its deviations as one JSON object, for the report and the study's bundle:
    ``locked`` and, when it is, ``plan``, ``sha256``, ``locked_at``; and ``deviations``."""
    frozen = frozen_plan(study)
    return {"locked": frozen is not None, **(frozen or {}), "deviations": deviations(study)}


def restore_preregistration(study: Study, data: dict) -> StudyPlan:
    """Write a locked plan and its recorded deviations from ``preregistration``'s data onto
    ``study`` (a study imported elsewhere, which must have no plan yet); ValueError if the
    plan does not match its SHA-256."""
    canonical = canonical_json(data["plan"])
    if hashlib.sha256(canonical.encode()).hexdigest() != data["sha256"]:
        raise ValueError("the plan does not match its SHA-256: it was changed after it was locked")
    with transaction.atomic():
        plan = StudyPlan.objects.create(study=study, canonical=canonical, sha256=data["sha256"],
                                        locked_at=data["locked_at"])
        rows = [PlanDeviation(study=study, at=row["at"], field=row["field"], old=row["old"], new=row["new"])
                for row in data["deviations"] if row["recorded"]]
        for row in rows:
            row.full_clean(exclude=["study"])  # a field name too long for its column, a time that is none
        PlanDeviation.objects.bulk_create(rows)
    return plan


# The signals: every path that opens or changes a study passes here.

def _study_saved(sender, instance: Study, raw: bool = False, **kwargs) -> None:
    if raw:  # a fixture being loaded: rows as they were, plans included
        return
    if instance.is_open and not StudyPlan.objects.filter(study=instance).exists():
        lock_plan(instance)
    else:
        record_deviations(instance)


def _part_changed(sender, instance: System | ControlSignal, raw: bool = False, origin=None, **kwargs) -> None:
    # A deletion of the whole study (or its owner) reaches its systems too: nothing to record then.
    if raw or (origin is not None and not (isinstance(origin, sender) or getattr(origin, "model", None) is sender)):
        return
    if StudyPlan.objects.filter(study_id=instance.study_id).exists():
        record_deviations(Study.objects.get(pk=instance.study_id))


def connect() -> None:
    """Connect the signals (``StudyappConfig.ready``)."""
    post_save.connect(_study_saved, sender=Study, dispatch_uid="plan-study-saved")
    for model in (System, ControlSignal):
        post_save.connect(_part_changed, sender=model, dispatch_uid=f"plan-{model.__name__}-saved")
        post_delete.connect(_part_changed, sender=model, dispatch_uid=f"plan-{model.__name__}-deleted")
