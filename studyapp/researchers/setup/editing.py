"""Editing a system's name, sampling temperature and display-figure mapping, or a control's
name, until the first participant starts (as ``removal``).

Nothing that changes where the motion comes from can be edited: another checkpoint,
other submitted motion or another path is another system or control (remove and add).
A new temperature changes every sampled clip of the system, so those clips are deleted
(rows, videos and sampled motion) and generating the stimuli again makes them anew; so are
the clips of a system whose mapping to the display figure is corrected. A new control name
changes no clip, but the control's description carries its name and every clip's content
key digests it, so its clips keep their videos and get their new keys; its export id, which
files made elsewhere are named by, stays.
"""

from __future__ import annotations

from django.db import transaction
from django.db.models import Q

from studyapp.bounds import check_field
from studyapp.models import ControlSignal, Stimulus, System
from studyapp.researchers.setup.removal import delete_files, require_not_started
from generation.render.display_figure import MappingError, complete_mapping, find_mapping, mapping_pose
from studyapp.stimuli.clips import content_key
from studyapp.stimuli.figure import rig_motion


class EditRefused(ValueError):
    """An edit that cannot be made; ``field`` names the form field at fault."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


def _check_name(item: System | ControlSignal, name: str) -> None:
    what = "system" if isinstance(item, System) else "control"
    if not name.strip():
        raise EditRefused("name", f"a {what} needs a name")
    if type(item).objects.filter(study=item.study, name=name).exclude(pk=item.pk).exists():
        raise EditRefused("name", f"this study already has a {what} named {name!r}")


def edit_system(system: System, name: str, temperature: float | None = None) -> int:
    """Rename ``system`` and, for a checkpoint system, set its sampling temperature (None:
    unchanged); how many clips were deleted to be sampled again at the new temperature."""
    _check_name(system, name)
    if temperature is not None and not system.checkpoint:
        raise EditRefused("temperature", f"{system.name} is not sampled from a checkpoint: it has no temperature")
    if temperature is not None and (problem := check_field(System, "temperature", temperature)):
        raise EditRefused("temperature", problem)
    resample = temperature is not None and temperature != system.temperature
    with transaction.atomic():
        require_not_started(system.study)
        stale = list(system.stimuli.select_related("study")) if resample else []
        Stimulus.objects.filter(pk__in=[s.pk for s in stale]).delete()
        system.name = name
        if resample:
            system.temperature = temperature
        system.save(update_fields=["name", "temperature"])
    delete_files(stale)
    return len(stale)


def correct_figure_mapping(system: System, table: dict[str, str]) -> int:
    """Keep the researcher's mapping ``table`` (point -> joint name; blank: as found) as the
    system's corrections (only where they differ from what was found), checked against its
    rig: EditRefused naming the points missing or the joints it does not have. The
    system's clips are deleted, to be drawn again; how many."""
    chosen = {point: joint for point, joint in table.items() if joint}
    motion = rig_motion(system)
    if motion is not None:
        found = find_mapping(motion.skeleton, mapping_pose(motion))
        try:
            complete_mapping(motion.skeleton, mapping_pose(motion), chosen)
        except MappingError as error:
            raise EditRefused("figure_mapping", str(error)) from None
        chosen = {point: joint for point, joint in chosen.items() if found.get(point) != joint}
    if problem := check_field(System, "figure_mapping", chosen):
        raise EditRefused("figure_mapping", problem)
    with transaction.atomic():
        require_not_started(system.study)
        stale = list(system.stimuli.all())
        Stimulus.objects.filter(pk__in=[s.pk for s in stale]).delete()
        system.figure_mapping = chosen
        system.save(update_fields=["figure_mapping"])
    delete_files(stale)
    return len(stale)


def rename_control(control: ControlSignal, name: str) -> None:
    """Rename ``control``; its clips keep their videos under new content keys, and its
    export id (``ControlSignal.export_id``) stays, so the files of exported controls and
    submitted motion still name it."""
    _check_name(control, name)
    with transaction.atomic():
        require_not_started(control.study)
        control.name = name
        control.control = {**control.control, "name": name}
        control.save(update_fields=["name", "control"])
        shown = Stimulus.objects.filter(Q(control=control) | Q(shown_control=control))  # mismatched clips too
        for stimulus in shown.select_related("system", "control", "shown_control"):  # a queued clip stays as it was
            Stimulus.objects.filter(pk=stimulus.pk).update(content_key=content_key(
                control.study, stimulus.system, stimulus.control, stimulus.seed, stimulus.shown_control))


__all__ = ["EditRefused", "correct_figure_mapping", "edit_system", "rename_control"]
