"""Removing a system or a control signal from a study, with its clips, until the first
participant starts: from then on the clips are part of what participants saw and rated.
Removing a whole study (the admin's delete) takes its clips' files with it.

Sampled motion (``sources.sampled_folder``) is named by content key, and two studies
whose clips have the same key share one file: a removal deletes only the files that no
remaining stimulus of any study refers to. The motion a study's bundle carried is that
study's alone (``sources.imported_sampled_path``) and goes with its clip.
"""

from __future__ import annotations

import re
import shutil

from django.db import transaction

from studyapp.models import ControlSignal, Rating, Stimulus, Study, System
from studyapp.preregistration.fixed import STARTED, StudyFixed, started
from studyapp.server.media_bucket import delete_clip
from studyapp.stimuli.sources import imported_sampled_folder, imported_sampled_path, sampled_folder

SAMPLED_NAME = re.compile(r"[0-9a-f]{64}\.npz")  # a content key; anything else there is not ours to delete


class SystemsFixed(StudyFixed):
    """Participants have started: the study's systems and controls are fixed (``plan.fixed``)."""


def require_not_started(study: Study) -> None:
    """SystemsFixed once anyone has started the study (call inside the change's transaction)."""
    if started(study):
        raise SystemsFixed(f"{STARTED}: its systems and controls are fixed")


def delete_files(stimuli: list[Stimulus]) -> None:
    """Delete the stimuli's video files and the sampled motion no stimulus refers to any
    more; call after the rows' deletion commits, so a failed delete leaves the files in place."""
    for stimulus in stimuli:
        delete_clip(stimulus.relative_path)
        imported_sampled_path(stimulus).unlink(missing_ok=True)  # its study's own: no other stimulus refers to it
    delete_unreferenced_samples()


def delete_unreferenced_samples() -> int:
    """Delete the sampled motion files no stimulus refers to any more; how many went.

    Only plain files directly in the folder and named by a content key are candidates.
    The files are listed before the keys are read, so a file whose stimulus was planned
    in between may go too; its clip is then sampled again when it is needed.
    """
    folder = sampled_folder()
    if not folder.is_dir():
        return 0
    candidates = [path for path in folder.iterdir()
                  if SAMPLED_NAME.fullmatch(path.name) and path.is_file() and not path.is_symlink()]
    referenced = set(Stimulus.objects.values_list("content_key", flat=True))
    unreferenced = [path for path in candidates if path.stem not in referenced]
    for path in unreferenced:
        path.unlink(missing_ok=True)
    return len(unreferenced)


def removal_summary(item: System | ControlSignal | Study) -> list[str]:
    """What removing ``item`` deletes, in words, one thing a line; the last line says
    what stays."""
    clips = item.stimuli.count()
    if isinstance(item, Study):
        participants = item.participants.count()
        ratings = Rating.objects.filter(assignment__participant__study=item).count()
        return [f"the study “{item.title}” and its settings",
                f"its {item.systems.count()} system(s), {item.controls.count()} control(s) and "
                f"{item.questions.count()} question(s)",
                f"its {clips} clip(s): their videos, and sampled motion no other study shares",
                f"its {participants} participant(s) with their {ratings} rating(s) and answers",
                "Kept: uploaded checkpoints and submitted motion (stored once by their content), and analysis "
                "reports already made. Download the ratings first if you need them."]
    if isinstance(item, System):
        sampled = " and sampled motion no other study shares" if item.checkpoint else ""
        kept = {System.SourceKind.CHECKPOINT: "its checkpoint file", System.SourceKind.SUBMITTED: "its submitted motion"}
        return [f"the system {item.name} ({item.get_role_display()})", f"its {clips} clip(s): their videos{sampled}",
                f"Kept: {kept[item.source_kind]}, stored once by its content for any system that uses it."
                if item.source_kind in kept else "Kept: every other system and its clips."]
    return [f"the control {item.name} ({item.origin})",
            f"its {clips} clip(s), one per system with motion for it: their videos and sampled motion",
            "Kept: every other control and each system's other clips."]


def remove(item: System | ControlSignal) -> int:
    """Delete ``item`` and its stimuli (rows, video files and sampled motion no other
    stimulus shares); returns how many clips went."""
    with transaction.atomic():
        require_not_started(item.study)
        stimuli = list(Stimulus.objects.filter(**{"system" if isinstance(item, System) else "control": item})
                       .select_related("study"))
        item.delete()  # its stimuli go with it (CASCADE)
    delete_files(stimuli)
    return len(stimuli)


def remove_study(study: Study) -> int:
    """Delete ``study`` with everything in it, its clips' videos and the sampled motion no
    other study shares; returns how many clips went."""
    with transaction.atomic():
        stimuli = list(study.stimuli.all())
        study.participants.all().delete()  # their assignments first: a rated clip is protected from deletion
        study.delete()
    delete_files(stimuli)
    shutil.rmtree(imported_sampled_folder(study), ignore_errors=True)  # what its bundle carried for clips renamed since
    return len(stimuli)


__all__ = ["SystemsFixed", "delete_files", "delete_unreferenced_samples", "remove", "remove_study", "removal_summary",
           "require_not_started"]
