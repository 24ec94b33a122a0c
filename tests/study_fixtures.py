"""Building studies for the study-app tests: systems, controls and rendered stimuli.

Stimuli here are real videos of real motion capture (one short natural clip rendered
once per test session and copied to each stimulus's token path), so that a browser can
play them to the end; which system "made" them does not matter to the rating flow.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from django.contrib.auth.models import User

from studyapp.models import Assignment, ControlSignal, Participant, Stimulus, Study, System

SYSTEMS = (("MoGlow", System.Role.MODEL), ("RNN", System.Role.MODEL), ("NAT", System.Role.NATURAL),
           ("BAD", System.Role.BAD))


def render_clip_video(bvh: Path, out: Path, seconds: float) -> Path:
    """A short H.264 clip of real motion (small, so a browser test plays it quickly)."""
    from generation.motion.clip_files import load_body_motion
    from generation.render import render_video

    motion = load_body_motion(bvh, fps=20.0, seconds=seconds)
    return render_video(motion, out, size=(320, 240))


def make_study(owner_name: str = "researcher", controls: int = 3, video: Path | None = None,
               clip_seconds: float = 4.0, systems: tuple[tuple[str, str], ...] = SYSTEMS, **fields) -> Study:
    """An open study with ``systems`` (name, role; default MoGlow, RNN, NAT and BAD) and one done
    stimulus per (system, control).

    With ``video``, every stimulus's file is a copy of it; otherwise no files exist
    (enough for tests that never play a clip).
    """
    owner, _ = User.objects.get_or_create(username=owner_name)
    defaults = {"title": "Naturalness of locomotion", "clips_per_participant": 6, "ratings_per_stimulus": 3,
                "training_clips": 2, "completion_code": "C0MPL3TE", "is_open": True,
                "platform": Study.Platform.PROLIFIC}
    fields = {**defaults, **fields}
    # Opened once its systems and clips exist, as a researcher opens one: opening locks its plan (studyapp.preregistration).
    is_open = fields.pop("is_open")
    study = Study.objects.create(owner=owner, **fields)
    signals = [ControlSignal.objects.create(study=study, name=f"control-{i}", origin=ControlSignal.Origin.HELD_OUT,
                                            control={"type": "path"}, source_clip=f"clip-{i}", seconds=clip_seconds)
               for i in range(controls)]
    for name, role in systems:
        system = System.objects.create(study=study, name=name, role=role)
        for signal in signals:
            stimulus = Stimulus.objects.create(study=study, system=system, control=signal, status=Stimulus.Status.DONE,
                                               content_key=f"{name}-{signal.name}", duration_s=clip_seconds)
            if video is not None:
                stimulus.video_path().parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(video, stimulus.video_path())
    if is_open:
        study.is_open = True
        study.save(update_fields=["is_open"])
    return study


def current_page(participant: Participant) -> list[Assignment]:
    """The clips of the participant's page on screen, in slot order (empty once every page is answered)."""
    first = participant.assignments.filter(rating__isnull=True).order_by("position").first()
    if first is None:
        return []
    return list(participant.assignments.filter(page=first.page).select_related("stimulus__system").order_by("slot"))


def current_clip(participant: Participant) -> Assignment | None:
    """The first clip of the participant's page on screen (the clip, in the single design); None once all are answered."""
    page = current_page(participant)
    return page[0] if page else None
