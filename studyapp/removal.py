"""Removing a system or a control signal from a study, with its clips, until the first
participant starts: from then on the clips are part of what participants saw and rated."""

from __future__ import annotations

from django.db import transaction

from studyapp.models import ControlSignal, Stimulus, Study, System


class SystemsFixed(Exception):
    """Participants have started: the study's systems and controls are fixed."""


def require_not_started(study: Study) -> None:
    """SystemsFixed once anyone has started the study (call inside the change's transaction)."""
    if study.participants.exists():
        raise SystemsFixed("participants have started this study: its systems and controls are fixed")


def delete_videos(stimuli: list[Stimulus]) -> None:
    """Delete the stimuli's video files; call after the rows' deletion commits, so a failed
    delete leaves the files in place."""
    for stimulus in stimuli:
        stimulus.video_path().unlink(missing_ok=True)


def remove(item: System | ControlSignal) -> int:
    """Delete ``item`` and its stimuli (rows and video files); returns how many clips went."""
    with transaction.atomic():
        require_not_started(item.study)
        stimuli = list(Stimulus.objects.filter(**{"system" if isinstance(item, System) else "control": item}))
        item.delete()  # its stimuli go with it (CASCADE)
    delete_videos(stimuli)
    return len(stimuli)


__all__ = ["SystemsFixed", "delete_videos", "remove", "require_not_started"]
