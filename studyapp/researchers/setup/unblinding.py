"""What could tell participants the systems apart besides their motion, for the readiness check.

A study is blind only if every clip looks alike apart from its motion. Systems whose
motion came at other frame rates, on other rigs or from other cameras are listed here,
each with what the study does about it: every clip is resampled to the study's rate and
drawn on the one display figure (``stimuli.figure``) by the study's camera. What the
study cannot undo is listed too: clips of one control that last differently, uploaded
videos (not drawn by the study at all), and a rig the figure cannot be placed on, which
stops the study from opening.
"""

from __future__ import annotations

from collections import defaultdict

from generation.motion.bvh import BVHError, bvh_frame_rate
from generation.render.display_figure import OPTIONAL_POINTS, MappingError
from studyapp.models import ControlSignal, Stimulus, Study, System
from studyapp.stimuli.controls import ControlError, study_options
from studyapp.stimuli.figure import rig_motion, system_mapping
from studyapp.stimuli.natural import natural_clip


def _source_rates(system: System) -> list[float]:
    """The frame rates the system's motion came at, as far as the study knows them."""
    if system.source_kind == System.SourceKind.SUBMITTED:
        return [float(fps) for fps in system.metadata.get("fps", []) if isinstance(fps, (int, float))]
    if system.source_kind == System.SourceKind.NATURAL:
        control = system.study.controls.filter(origin=ControlSignal.Origin.HELD_OUT).exclude(source_clip="").first()
        if control is None:
            return []
        try:
            return [bvh_frame_rate(natural_clip(control.source_clip, control.natural.get("folders", ())))]
        except (BVHError, OSError):
            return []
    if system.checkpoint:
        return [float(system.dataset_options().fps)]
    return []


def _rates(study: Study, systems: list[System]) -> str | None:
    rates = {}
    for system in systems:
        try:
            rates[system.name] = _source_rates(system)
        except (OSError, ValueError):  # a row the study cannot read: its own page says why
            rates[system.name] = []
    if len({fps for found in rates.values() for fps in found}) < 2:
        return None
    fps = study_options(study).fps
    listed = ", ".join(f"{name} {'/'.join(f'{r:g}' for r in found)} fps" for name, found in rates.items() if found)
    return f"the systems' motion came at different frame rates ({listed}): every clip is resampled to the study's " \
           f"{fps:g} fps before it is drawn"


def _rigs(systems: list[System]) -> tuple[list[str], list[str]]:
    """(problems, warnings) of the systems' rigs: a rig that lacks a point, and rigs that differ."""
    problems, rigs, hands = [], {}, {}
    for system in systems:
        try:
            motion = rig_motion(system)
            if motion is None:
                continue
            mapping = system_mapping(system, motion)
        except MappingError as error:
            problems.append(f"{error}: correct its mapping on its figure page (systems), or its clips cannot be drawn "
                            "on the study's display figure")
            continue
        except (OSError, ValueError):  # its clips fail with the reason, which the stimuli page shows
            continue
        rigs[system.name] = motion.skeleton.n_joints
        hands[system.name] = all(point in mapping for point in OPTIONAL_POINTS)
    warnings = []
    if len(set(rigs.values())) > 1 or (rigs and len(rigs) < len(systems)):
        listed = ", ".join(f"{name} {joints} joints" for name, joints in rigs.items())
        warnings.append(f"the systems' skeletons differ ({listed}): every clip is drawn on the study's one display "
                        "figure, each rig's joints mapped to its points (see each system's figure page)")
    if any(hands.values()) and not all(hands.values()):
        some = [name for name, has in hands.items() if has]
        warnings.append(f"only {', '.join(some)} {'has' if len(some) == 1 else 'have'} hands: the display figure draws "
                        "none, so that no system shows by them")
    return problems, warnings


def _lengths(study: Study) -> str | None:
    """Controls whose finished clips last differently from one system to another."""
    seconds: dict[str, dict[str, float]] = defaultdict(dict)
    done = study.stimuli.filter(status=Stimulus.Status.DONE, shown_control=None).exclude(control=None)
    for control, system, duration in done.values_list("control__name", "system__name", "duration_s"):
        if duration is not None:
            seconds[control][system] = duration
    uneven = {control: by for control, by in seconds.items() if max(by.values()) - min(by.values()) > 0.06}
    if not uneven:
        return None
    control, by = next(iter(uneven.items()))
    listed = ", ".join(f"{name} {s:.2f} s" for name, s in sorted(by.items()))
    more = f" and {len(uneven) - 1} more control(s)" if len(uneven) > 1 else ""
    return f"clips of one control last differently ({control}: {listed}{more}): the display figure cannot hide a " \
           "length, so participants may tell the systems by it; give every system the control's whole length"


def _cameras(systems: list[System]) -> str | None:
    videos = [system.name for system in systems
              if system.source_kind == System.SourceKind.VIDEO and system.role == System.Role.MODEL]
    if not videos:
        return None
    return f"{', '.join(videos)} {'is' if len(videos) == 1 else 'are'} uploaded video: not drawn by the study's " \
           "camera nor on its display figure, so participants may tell them from the rendered clips; submit the " \
           "motion instead"


def unblinding(study: Study) -> tuple[list[str], list[str]]:
    """(problems, warnings): what could tell participants the systems apart besides their
    motion, each with what the study does about it; a problem stops the study opening."""
    systems = list(study.systems.order_by("role", "name"))
    drawn = [system for system in systems if system.source_kind != System.SourceKind.VIDEO]
    problems, warnings = _rigs(drawn)
    try:
        rates = _rates(study, drawn)
    except ControlError:  # the checkpoints disagree: their page says so
        rates = None
    warnings += [line for line in (rates, _lengths(study), _cameras(systems)) if line]
    return problems, warnings


__all__ = ["unblinding"]
