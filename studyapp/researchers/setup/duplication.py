"""A study's copy: its settings, systems, controls, questions and finished clips, without
its participants, closed, for a new round or another design of the same comparison.

The clips are not rendered again: each copied clip's video is a hard link to the
original's file (a copy where the file system has no links) under a token of its own, so
removing either study leaves the other's videos in place; sampled motion is found by the
clip's content key, which the copy keeps. ``copy_contents`` adds what a study lacks of
another's and may be repeated (the demo's side-by-side study follows its single study so).
"""

from __future__ import annotations

from django.db import transaction

from studyapp.models import ControlSignal, Question, Stimulus, Study, System
from studyapp.server.media_bucket import copy_clip, delete_clip

# What a copy starts without: who owns it and whether it is open are set anew, the rest is made anew.
NOT_COPIED = {"id", "owner", "key", "title", "is_open", "previewed_at", "created", "updated"}


def copy_contents(source: Study, target: Study) -> int:
    """Give ``target`` the systems, controls, questions and finished clips of ``source``
    that it lacks (matched by name, and clips by content key); how many clips were added."""
    linked: list[Stimulus] = []
    try:
        with transaction.atomic():
            _copy_rows(source, target, linked)
    except BaseException:  # no video is left behind for a row that was not kept
        for clip in linked:
            delete_clip(clip.relative_path)
        raise
    return len(linked)


def _fields(row: System | ControlSignal | Question) -> dict:
    """What a copy of ``row`` in another study takes from it: every field but its id, its
    study, its name (the copy is found by it) and when it was made."""
    return {f.name: getattr(row, f.name) for f in type(row)._meta.concrete_fields
            if f.name not in ("id", "study", "name", "created")}


def _copy_rows(source: Study, target: Study, linked: list[Stimulus]) -> None:
    """The rows of ``copy_contents``; each clip whose video is linked is added to ``linked``."""
    systems = {s.pk: System.objects.get_or_create(study=target, name=s.name, defaults=_fields(s))[0]
               for s in source.systems.all()}
    controls = {c.pk: ControlSignal.objects.get_or_create(study=target, name=c.name, defaults=_fields(c))[0]
                for c in source.controls.all()}
    for question in source.questions.all():
        Question.objects.get_or_create(study=target, name=question.name, defaults=_fields(question))
    copied = set(target.stimuli.values_list("content_key", flat=True))
    for clip in source.stimuli.filter(status=Stimulus.Status.DONE).exclude(content_key__in=copied):
        twin = Stimulus.objects.create(
            study=target, system=systems[clip.system_id], control=controls.get(clip.control_id), seed=clip.seed,
            content_key=clip.content_key, status=Stimulus.Status.DONE, duration_s=clip.duration_s)
        copy_clip(clip.relative_path, twin.relative_path)
        linked.append(twin)


def duplicate_study(study: Study, title: str | None = None) -> Study:
    """A closed copy of ``study`` (``copy_contents``) under ``title`` (default "Copy of ...")."""
    fields = {f.name: getattr(study, f.name) for f in Study._meta.concrete_fields if f.name not in NOT_COPIED}
    with transaction.atomic():
        copy = Study.objects.create(owner=study.owner, title=title or f"Copy of {study.title}"[:200], **fields)
        copy_contents(study, copy)
    return copy


__all__ = ["copy_contents", "duplicate_study"]
