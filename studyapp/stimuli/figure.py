"""The study's display figure: every clip, whatever its system's rig, drawn on one figure.

The figure has the bone lengths of the study's reference skeleton: the NAT data's (the
take of the study's first held-out control, the data its checkpoints learnt from) where
the study has held-out controls, else the first submitted motion's rig
(``reference_rig``). Each system's joints are mapped to the figure's points as its rig's
names and shape say (``generation.render.display_figure.find_mapping``, found on each
clip), with the researcher's corrections over it (``System.figure_mapping``, set on the
system's figure page, in the definition file and carried by a bundle); a rig whose
mapping leaves a point out is refused naming it. The figure is worked out when the
stimuli are planned and kept in ``Study.display_figure``, which every clip's content key
digests; the hands are part of it only where every system's rig has them. A study of
checkpoints alone on synthetic controls has no rig to read before sampling: each clip is
then drawn on the rest lengths of its own rig, which is the one the checkpoints share.
The motion a system was given stays stored and is exported as it came: only the rendered
clip is retargeted.
"""

from __future__ import annotations

from generation.motion.types import Motion
from generation.render.display_figure import (OPTIONAL_POINTS, POINTS, DisplayFigure, MappingError, complete_mapping,
                                              find_mapping, mapping_pose, rest_positions)
from generation.render.retarget import retarget
from studyapp.models import ControlSignal, Stimulus, StoredDataError, Study, System, json_object
from studyapp.stimuli.controls import natural_options
from studyapp.stimuli.natural import natural_motion
from studyapp.stimuli.sources import sampled_path, source_of


def corrections(system: System | None) -> dict[str, str]:
    """The researcher's corrections of the system's mapping (point -> joint name)."""
    return {} if system is None else json_object(system, "figure_mapping")


def system_mapping(system: System | None, motion: Motion) -> dict[str, str]:
    """How ``motion``'s joints (a clip of ``system``; None: the NAT data's, no system) map
    to the figure's points: found from its rig, the researcher's corrections over it;
    MappingError naming the system and the points it lacks."""
    try:
        return complete_mapping(motion.skeleton, mapping_pose(motion), corrections(system))
    except MappingError as error:
        raise MappingError(f"{system.name if system else 'the NAT data'}: {error}", error.missing) from None


def natural_take(study: Study) -> Motion | None:
    """The NAT data's rig: the take of the study's first held-out control, as NAT reads it."""
    control = (study.controls.filter(origin=ControlSignal.Origin.HELD_OUT).exclude(source_clip="")
               .order_by("pk").first())
    return None if control is None else natural_motion(control, natural_options(control))


def rig_motion(system: System) -> Motion | None:
    """A clip of the system's motion as it came, on its rig: NAT's first held-out clip,
    the first stored clip of submitted motion; for a checkpoint the NAT data it learnt from,
    else its first sampled clip; None where there is none yet (uploaded videos)."""
    kind = system.source_kind
    if kind == System.SourceKind.VIDEO:
        return None
    if kind == System.SourceKind.CHECKPOINT:
        if (take := natural_take(system.study)) is not None:
            return take
        stimulus = next((s for s in system.stimuli.filter(shown_control=None).select_related("control")
                         if sampled_path(s).is_file()), None)
        return None if stimulus is None else source_of(system).clip(stimulus).motion
    controls = source_of(system).controls(system, list(system.study.controls.order_by("pk")))
    if not controls:
        return None
    return source_of(system).clip(Stimulus(study=system.study, system=system, control=controls[0])).motion


def reference_rig(study: Study) -> tuple[System | None, Motion] | None:
    """The rig that gives the figure its bone lengths, with its system (None for the NAT
    data of a study without NAT): the NAT data's, else the first submitted motion's; None
    where the study has neither."""
    natural = study.systems.filter(role=System.Role.NATURAL).first()
    if (take := natural_take(study)) is not None:
        return natural, take
    submitted = study.systems.filter(kind=System.SourceKind.SUBMITTED).order_by("pk").first()
    motion = None if submitted is None else rig_motion(submitted)
    return None if motion is None else (submitted, motion)


def work_out_figure(study: Study) -> DisplayFigure | None:
    """The study's figure from its reference rig, kept in ``Study.display_figure``; None,
    and nothing kept, where it has none. MappingError where the reference rig lacks a point."""
    reference = reference_rig(study)
    if reference is None:
        return None
    system, motion = reference
    figure = DisplayFigure.of_motion(motion, system_mapping(system, motion))
    hands = set(OPTIONAL_POINTS)
    for other in study.systems.exclude(kind=System.SourceKind.VIDEO):
        try:
            clip = rig_motion(other)
            hands &= set(system_mapping(other, clip)) if clip is not None else set()
        except (OSError, ValueError):  # its clips fail with the reason; the others need no hands
            hands = set()
    figure = figure.with_points(hands)
    Study.objects.filter(pk=study.pk).update(display_figure=figure.to_dict())
    study.display_figure = figure.to_dict()
    return figure


def study_figure(study: Study, system: System, motion: Motion) -> DisplayFigure:
    """The figure kept for the study; where none is (checkpoints alone on synthetic
    controls), the rest lengths of ``motion``'s rig, a clip of ``system``. StoredDataError
    where the study holds something else."""
    if study.display_figure == {}:
        rest = Motion(rest_positions(motion.skeleton)[None], motion.fps, motion.skeleton)
        return DisplayFigure.of_motion(rest, system_mapping(system, motion)).with_points(set())
    try:
        return DisplayFigure.from_dict(json_object(study, "display_figure"))
    except MappingError as error:
        raise StoredDataError(study, "display_figure", f"holds no display figure ({error}): generate the stimuli "
                                                       "again") from None


def on_display_figure(system: System, motion: Motion, study: Study) -> Motion:
    """``motion``, a clip of ``system``, retargeted onto the study's display figure."""
    return retarget(motion, system_mapping(system, motion), study_figure(study, system, motion))


def figure_table(system: System) -> dict:
    """What the system's figure page shows: the rig's joints and, for every point, the
    joint found and the one used (corrected); ``problem`` says what is missing."""
    try:
        motion = rig_motion(system)
    except (OSError, ValueError) as error:
        return {"joints": [], "rows": [], "problem": f"its motion could not be read: {error}"}
    if system.source_kind == System.SourceKind.VIDEO:
        return {"joints": [], "rows": [], "problem": "uploaded videos are shown as they are: they are not drawn on "
                                                     "the study's display figure"}
    if motion is None:
        return {"joints": [], "rows": [], "problem": "no clip of its motion yet (a checkpoint's rig is read when "
                                                     "its first clip is sampled)"}
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
