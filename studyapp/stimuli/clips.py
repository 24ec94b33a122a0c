"""Generating a study's stimuli: one row per (system, control) pair, then the clip itself.

``plan_stimuli`` makes the rows. Each row's ``content_key`` digests everything its clip
depends on (the checkpoint's digest or the natural clip, the control, seed, temperature,
camera, video size and code version), so planning again finds the same rows and never
duplicates a stimulus. Each system gets the controls its source has motion for
(``sources``): checkpoints every control, NAT the held-out ones (a synthetic path has no
natural clip), submitted motion those it was submitted for, uploaded videos none. A
design whose pages show clips made for other controls (appropriateness) adds those
mismatched clips (``mismatched``): its system's motion for the partner control, drawn
over the shown control's path; every clip of such a study is drawn over the path of the
control its page shows, with the camera following that path (``over_shown_control``).

``render_stimulus`` is the work a task does: ask the system's source for the motion and
render it, whatever the source, on the study's display figure (``figure``) with the
study's camera and write ``MEDIA_ROOT/stimuli/<token>.mp4`` atomically. A
killed attempt leaves only a hidden ``.<token>.mp4.*.part`` temporary, which the next
attempt removes and the media view never serves. With a bucket (``MEDIA_BUCKET_URL``) the
checked video is uploaded there instead (``studyapp.server.media_bucket``).

This module knows nothing of the task queue: ``dispatch`` sends the rows to the
workers, and ``tasks`` calls ``claim``, ``render_stimulus`` and ``finish``.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from contextlib import suppress
from importlib import metadata

from django.db import transaction
from django.db.models import F
from django.utils import timezone

import numpy as np

from generation.control import PathControl
from generation.motion.root import root_trajectory
from generation.motion.types import Motion
from generation.render import Camera, render_video
from generation.render.video_check import VideoError, check_rendered_video
from studyapp.designs.registry import design_of
from studyapp.models import ControlSignal, Stimulus, Study, System
from studyapp.preregistration.fixed import require_seed_allowed
from studyapp.server.media_bucket import clip_destination, clip_exists
from studyapp.stimuli.controls import study_options
from studyapp.stimuli.figure import on_display_figure, work_out_figure
from studyapp.stimuli.mismatched import mismatched_clips
from studyapp.stimuli.sources import Clip, source_of

# The package version, not the git commit: a commit that changes no rendering code
# must not make every stimulus new.
try:
    CODE_VERSION = metadata.version("motion-study")
except metadata.PackageNotFoundError:
    CODE_VERSION = "unknown"



def content_key(study: Study, system: System, control: ControlSignal, seed: int,
                shown: ControlSignal | None = None) -> str:
    """SHA-256 of everything the clip of ``system`` for ``control`` depends on (shown
    against the ``shown`` control's path, for a mismatched clip)."""
    parts = {
        "role": system.role,
        **source_of(system).identity(system, control, seed),  # source, seed, temperature
        "control": control.control,
        "seconds": control.seconds,
        "camera": study.camera,
        "size": [study.video_width, study.video_height],
        "code": CODE_VERSION,
    }
    # The figure every clip is drawn on, and the system's corrections of its mapping to it; left out
    # where empty, so that a clip planned before studies had a figure (an older bundle's) keeps its key.
    if study.display_figure:
        parts["figure"] = study.display_figure
    if system.figure_mapping:
        parts["figure_mapping"] = system.figure_mapping
    if design_of(study).mismatched_clips:  # drawn over the path of the control its page shows
        parts["drawn_over"] = (shown or control).control
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def _pairs(study: Study) -> list[tuple[System, ControlSignal, ControlSignal | None]]:
    """Each system with each control its source has motion for (shown on its own, None),
    and the mismatched clips where the study's pages show them."""
    controls = list(study.controls.all())
    own = [(system, control, None) for system in study.systems.all()
           for control in source_of(system).controls(system, controls)]
    return own + (mismatched_clips(study) if design_of(study).mismatched_clips else [])


def plan_stimuli(study: Study, seed: int = 0) -> tuple[list[Stimulus], int]:
    """The rows of every (system, control) pair and mismatched clip, created where missing;
    (rows, how many were new); StudyFixed where the seed would add a second set of clips to a
    study whose plan is locked."""
    stimuli, created = [], 0
    # The clips' content keys digest the figure they are drawn on. A rig that cannot be read
    # or mapped fails its clips with the reason when they are rendered (and the readiness check lists it).
    with suppress(OSError, ValueError):
        work_out_figure(study)
    with transaction.atomic():
        require_seed_allowed(study, seed)
        for system, control, shown in _pairs(study):
            stimulus, new = Stimulus.objects.get_or_create(
                study=study, content_key=content_key(study, system, control, seed, shown),
                defaults={"system": system, "control": control, "seed": seed, "shown_control": shown})
            stimuli.append(stimulus)
            created += new
    return stimuli, created


def progress(study: Study) -> dict:
    """Counts by status and the failed rows with their reasons, for the progress page."""
    counts = Counter(study.stimuli.values_list("status", flat=True))
    failed = study.stimuli.filter(status=Stimulus.Status.FAILED).select_related("system", "control")
    return {
        "total": sum(counts.values()),
        "counts": {status: counts.get(status, 0) for status in Stimulus.Status.values},
        "failed": [{"id": s.pk, "system": s.system.name, "control": s.control.name if s.control else "",
                    "error": s.error, "attempts": s.attempts} for s in failed],
    }


# --- the work of one task ---------------------------------------------------------

def sample_ahead(sent: list[tuple[int, str]]) -> list[tuple[int, str]]:
    """Sample the motion of the stimuli a sampling task was sent for, as (stimulus id, the
    task id its render was sent under) pairs, each system's in one call of its source;
    the pairs sampled. A row sent again since (another task id) is left to its later
    task; a row that fails is marked failed with the reason, and the others go on."""
    task_ids = dict(sent)
    rows = Stimulus.objects.filter(pk__in=task_ids).select_related("study", "system", "control")
    by_system: dict[int, list[Stimulus]] = {}
    for stimulus in rows:
        if stimulus.task_id == task_ids[stimulus.pk]:
            by_system.setdefault(stimulus.system_id, []).append(stimulus)
    ready = []
    for stimuli in by_system.values():
        motions = {stimulus.pk: motion_row(stimulus) for stimulus in stimuli}  # a mismatched clip's is another's
        unique = list({row.pk: row for row in motions.values()}.values())
        failed = source_of(stimuli[0].system).sample_ahead(stimuli[0].system, unique)
        for stimulus in stimuli:
            error = failed.get(motions[stimulus.pk].pk)
            if error is not None:  # the reason is shown on the progress page, where it can be retried
                finish(stimulus, error=f"{type(error).__name__}: {error}")
            else:
                ready.append((stimulus.pk, stimulus.task_id))
    return ready


def remove_partial_files(stimulus: Stimulus) -> int:
    """Delete temporaries a killed attempt left beside the video; how many there were."""
    target = stimulus.video_path()
    stale = list(target.parent.glob(f".{target.name}.*.part")) if target.parent.is_dir() else []
    for path in stale:
        path.unlink(missing_ok=True)
    return len(stale)


def motion_row(stimulus: Stimulus) -> Stimulus:
    """The stimulus whose motion a clip shows: itself, or for a mismatched clip its system's
    clip of the control it was made for (so that motion is sampled once)."""
    if stimulus.shown_control_id is None:
        return stimulus
    key = content_key(stimulus.study, stimulus.system, stimulus.control, stimulus.seed)
    own = (Stimulus.objects.select_related("study", "system", "control")
           .filter(study=stimulus.study_id, content_key=key).first())
    if own is None:
        raise ValueError(f"the clip of {stimulus.system.name} for {stimulus.control.name} is not planned: "
                         "generate the stimuli again")
    return own


def render_stimulus(stimulus: Stimulus) -> float:
    """Write the stimulus's video atomically and check it whole against its clip (every
    frame decodes, as many frames lasting as long as the motion); its duration in seconds.
    A video that fails the check is removed, so no finished row points at it."""
    remove_partial_files(stimulus)
    motion, floor, drawn = drawn_clip(stimulus)
    study = stimulus.study
    with clip_destination(stimulus.relative_path) as target:
        path = render_video(motion, target, camera=Camera.from_dict(study.camera),
                            size=(study.video_width, study.video_height), root_path=floor, control_path=drawn)
        try:
            return check_rendered_video(path, motion).seconds
        except VideoError:
            path.unlink(missing_ok=True)
            raise


def drawn_clip(stimulus: Stimulus) -> tuple[Motion, np.ndarray, np.ndarray | None]:
    """What the stimulus's video draws: (its system's motion on the study's display figure,
    the floor path under it, the shown control's path where its page shows one). The
    motion as it came stays stored, for the motion export."""
    if stimulus.control is None:
        raise ValueError("an uploaded video has nothing to generate")
    clip = source_of(stimulus.system).clip(motion_row(stimulus))
    motion, floor, drawn = clip.motion, clip.floor, None
    if design_of(stimulus.study).mismatched_clips:
        motion, floor, drawn = over_shown_control(stimulus, clip)
    return on_display_figure(stimulus.system, motion, stimulus.study), floor, drawn


def over_shown_control(stimulus: Stimulus, clip: Clip) -> tuple[Motion, np.ndarray, np.ndarray | None]:
    """A clip as its page shows it: (the motion, in the frame where every control's path
    starts and cut to the shown control's length; the figure's own floor path; the shown
    control's path, None for a label control). Every system's clip of one page's control,
    matched or not, is then drawn over the same path by a camera following it."""
    shown = (stimulus.shown_control or stimulus.control).signal()
    root = study_options(stimulus.study).root
    motion = clip.on_control_path(shown.n_frames, root)
    path = shown.path().xz[:motion.n_frames] if isinstance(shown, PathControl) else None
    return motion, root_trajectory(motion, root).xz, path


def claim(stimulus_id: int, task_id: str) -> Stimulus | None:
    """Mark the row running and count the attempt; None when there is nothing to do:
    the row is gone, done, or was sent again since this task's message (another task
    id), in which case the later task does the work."""
    with transaction.atomic():
        # Only the row itself is locked: PostgreSQL refuses to lock the nullable side
        # (control) of the outer join, and the study and system need no lock.
        stimulus = (Stimulus.objects.select_for_update(of=("self",)).select_related("study", "system", "control")
                    .filter(pk=stimulus_id).first())
        if stimulus is None or stimulus.task_id != task_id:
            return None
        if stimulus.status == Stimulus.Status.DONE and clip_exists(stimulus.relative_path):
            return None
        Stimulus.objects.filter(pk=stimulus.pk).update(status=Stimulus.Status.RUNNING, attempts=F("attempts") + 1,
                                                       error="", updated=timezone.now())
    stimulus.refresh_from_db()
    return stimulus


def finish(stimulus: Stimulus, duration_s: float | None = None, error: str = "") -> None:
    """Record the attempt's outcome: done with its duration, or failed with the reason."""
    status = Stimulus.Status.FAILED if error else Stimulus.Status.DONE
    Stimulus.objects.filter(pk=stimulus.pk, task_id=stimulus.task_id).update(
        status=status, duration_s=duration_s, error=error, updated=timezone.now())


__all__ = ["claim", "content_key", "drawn_clip", "finish", "motion_row", "over_shown_control", "plan_stimuli", "progress", "remove_partial_files", "render_stimulus",
           "sample_ahead"]
