"""The study's display figure: every clip, whatever its system's rig, drawn on one figure.

The figure has the bone lengths of the study's reference skeleton: NAT's rig where the
study has NAT, else the first system's with motion to read (``reference_system``). Each
system's joints are mapped to the figure's points as its rig's names and shape say
(``generation.render.display_figure.find_mapping``, found on each clip), with the
researcher's corrections over it (``System.figure_mapping``, set on the system's figure
page, in the definition file and carried by a bundle). A rig whose mapping leaves a
point out is refused naming it. The figure is worked out when the stimuli are planned
and kept in ``Study.display_figure``, which every clip's content key digests; the
hands are part of it only where every system's rig has them. The motion a system was
given is stored and exported as it came: only the rendered clip is retargeted.
"""

from __future__ import annotations

from django.db import transaction

from generation.motion.types import Motion
from generation.render.display_figure import (OPTIONAL_POINTS, POINTS, DisplayFigure, MappingError, complete_mapping,
                                              find_mapping, mapping_pose)
from generation.render.retarget import retarget
from studyapp.models import Stimulus, StoredDataError, Study, System, json_object
from studyapp.stimuli.sources import sampled_path, source_of


def corrections(system: System) -> dict[str, str]:
    """The researcher's corrections of the system's mapping (point -> joint name)."""
    return json_object(system, "figure_mapping")


def system_mapping(system: System, motion: Motion) -> dict[str, str]:
    """How ``motion``'s joints (a clip of ``system``) map to the figure's points: found from
    its rig, the researcher's corrections over it; MappingError naming the system and the
    points it lacks."""
    try:
        return complete_mapping(motion.skeleton, mapping_pose(motion), corrections(system))
    except MappingError as error:
        raise MappingError(f"{system.name}: {error}", error.missing) from None


def rig_motion(system: System) -> Motion | None:
    """A clip of the system's motion as it came, on its rig: NAT's first held-out clip,
    the first stored clip of submitted motion, the first clip sampled from a checkpoint;
    None where there is none yet (a checkpoint not sampled, uploaded videos)."""
    kind = system.source_kind
    if kind == System.SourceKind.VIDEO:
        return None
    if kind == System.SourceKind.CHECKPOINT:
        stimulus = next((s for s in system.stimuli.filter(shown_control=None).select_related("control")
                         if sampled_path(s).is_file()), None)
        return None if stimulus is None else source_of(system).clip(stimulus).motion
    controls = source_of(system).controls(system, list(system.study.controls.order_by("pk")))
    if not controls:
        return None
    return source_of(system).clip(Stimulus(study=system.study, system=system, control=controls[0])).motion


def reference_system(study: Study) -> System | None:
    """The system whose rig gives the figure its bone lengths: NAT, else the first with motion."""
    systems = sorted(study.systems.all(), key=lambda s: (s.role != System.Role.NATURAL, s.pk))
    return next((system for system in systems if system.source_kind != System.SourceKind.VIDEO), None)


def work_out_figure(study: Study) -> DisplayFigure | None:
    """The study's figure from its reference system's rig, kept in ``Study.display_figure``
    (None, and nothing kept, while no system has motion to read); MappingError where a
    rig lacks a point."""
    reference = reference_system(study)
    motion = rig_motion(reference) if reference is not None else None
    if motion is None:
        return None
    figure = DisplayFigure.of_motion(motion, system_mapping(reference, motion))
    hands = set(OPTIONAL_POINTS)
    for system in study.systems.exclude(kind=System.SourceKind.VIDEO):
        try:
            clip = rig_motion(system)
            hands &= set(system_mapping(system, clip)) if clip is not None else set()
        except (OSError, ValueError):  # its clips fail with the reason; the others need no hands
            hands = set()
    figure = figure.with_points(hands)
    with transaction.atomic():
        Study.objects.filter(pk=study.pk).update(display_figure=figure.to_dict())
    study.display_figure = figure.to_dict()
    return figure


def study_figure(study: Study) -> DisplayFigure:
    """The figure kept for the study, worked out where none is kept yet (StoredDataError
    where it holds no figure)."""
    if study.display_figure == {} and (figure := work_out_figure(study)) is not None:  # a clip made by hand
        return figure
    try:
        return DisplayFigure.from_dict(json_object(study, "display_figure"))
    except MappingError as error:
        raise StoredDataError(study, "display_figure", f"holds no display figure ({error}): generate the stimuli "
                                                       "again") from None


def on_display_figure(system: System, motion: Motion, study: Study) -> Motion:
    """``motion``, a clip of ``system``, retargeted onto the study's display figure."""
    return retarget(motion, system_mapping(system, motion), study_figure(study))


def figure_table(system: System) -> dict:
    """What the system's figure page shows: the rig's joints and, for every point, the
    joint found and the one used (corrected); ``problem`` says what is missing."""
    try:
        motion = rig_motion(system)
    except (OSError, ValueError) as error:
        return {"joints": [], "rows": [], "problem": f"its motion could not be read: {error}"}
    if motion is None:
        return {"joints": [], "rows": [], "problem": "no clip of its motion yet (a checkpoint's is found when its "
                                                     "first clip is sampled)"}
    found = find_mapping(motion.skeleton, mapping_pose(motion))
    used = {**found, **corrections(system)}
    rows = [{"point": point, "found": found.get(point, ""), "used": used.get(point, ""),
             "optional": point in OPTIONAL_POINTS} for point, _ in POINTS]
    try:
        system_mapping(system, motion)
        problem = ""
    except MappingError as error:
        problem = str(error)
    return {"joints": list(motion.skeleton.names), "rows": rows, "problem": problem}


__all__ = ["corrections", "figure_table", "on_display_figure", "rig_motion", "study_figure",
           "system_mapping", "work_out_figure"]
