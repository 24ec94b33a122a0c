"""Removing a system or a control signal from a study, with its clips, until the first
participant starts: from then on the clips are part of what participants saw and rated."""

from __future__ import annotations

from django.db import transaction

from studyapp.models import ControlSignal, Stimulus, System


class RemovalRefused(Exception):
    """Participants have started: the study's systems and controls are fixed."""


def remove(item: System | ControlSignal) -> int:
    """Delete ``item`` and its stimuli (rows and video files); returns how many clips went."""
    with transaction.atomic():
        if item.study.participants.exists():
            raise RemovalRefused("participants have started this study: its systems and controls are fixed")
        stimuli = list(Stimulus.objects.filter(**{"system" if isinstance(item, System) else "control": item}))
        item.delete()  # its stimuli go with it (CASCADE)
    for stimulus in stimuli:  # after the commit: a failed delete leaves the files in place
        stimulus.video_path().unlink(missing_ok=True)
    return len(stimuli)


__all__ = ["RemovalRefused", "remove"]
