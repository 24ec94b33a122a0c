"""An appropriateness study for the tests: path controls whose partners the mismatch rule
knows, model systems, NAT and BAD, and every planned clip marked finished.

The controls stand for held-out takes (each names a source clip, so NAT has a clip of
it): a left and a right curve (each the other's partner, and its attention partner, so
neither makes a NAT check), a straight walk and a zig-zag (each the other's partner; a
sharp left turn their attention partner) and the sharp left turn itself. Two synthetic paths join them, which NAT has
no clip of: a circle (its partner a take) and a stand-still (no partner: nothing else
stands).
"""

from __future__ import annotations

import shutil
from pathlib import Path

from django.contrib.auth.models import User

from generation.control import preset_path, synthetic_path
from studyapp.models import ControlSignal, Stimulus, Study, System
from studyapp.stimuli.clips import plan_stimuli

TAKES = {
    "left": [{"type": "curve", "speed": 110, "turn_rate": 30, "seconds": 4}],
    "right": [{"type": "curve", "speed": 110, "turn_rate": -30, "seconds": 4}],
    "straight": [{"type": "straight", "speed": 115, "seconds": 4}],
    "zigzag": [{"type": "curve", "speed": 110, "turn_rate": 40, "seconds": 1.5},
               {"type": "curve", "speed": 110, "turn_rate": -40, "seconds": 2.5}],
    "sharp-left": [{"type": "curve", "speed": 105, "turn_rate": 60, "seconds": 4}],
}
MODELS = ("MoGlow", "RNN")


def make_appropriateness_study(owner_name: str = "researcher", video: Path | None = None, clip_seconds: float = 4.0,
                               **fields) -> Study:
    """An open appropriateness study with MoGlow, RNN, NAT and BAD and every planned clip
    finished (with ``video`` as every clip's file, or no files)."""
    owner, _ = User.objects.get_or_create(username=owner_name)
    defaults = {"title": "Does the motion follow its path?", "design": "appropriateness", "pages_per_participant": 6,
                "ratings_per_stimulus": 10, "training_clips": 2, "bad_checks": 1, "completion_code": "C0MPL3TE",
                "is_open": True, "platform": Study.Platform.PROLIFIC}
    fields = {**defaults, **fields}
    is_open = fields.pop("is_open")  # opened once its clips exist, as a researcher opens one (studyapp.preregistration)
    study = Study.objects.create(owner=owner, **fields)
    for name, segments in TAKES.items():
        control = synthetic_path({"name": name, "segments": segments}, 20.0)
        ControlSignal.objects.create(study=study, name=name, origin=ControlSignal.Origin.HELD_OUT,
                                     control=control.to_dict(), source_clip=f"takes/{name}.bvh", seconds=4.0)
    for preset in ("walk-circle", "stand-still"):
        path = preset_path(preset, 20.0)
        ControlSignal.objects.create(study=study, name=path.name, origin=ControlSignal.Origin.SYNTHETIC,
                                     control=path.to_dict(), seconds=4.0)
    for name in MODELS:
        System.objects.create(study=study, name=name, checkpoint=f"{name}.safetensors", checkpoint_digest=name * 8,
                              kind="moglow")
    System.objects.create(study=study, name="NAT", role=System.Role.NATURAL, kind=System.SourceKind.NATURAL)
    System.objects.create(study=study, name="Early", role=System.Role.BAD, checkpoint="early.safetensors",
                          checkpoint_digest="early" * 8, kind="moglow")
    stimuli, _ = plan_stimuli(study)
    Stimulus.objects.filter(pk__in=[s.pk for s in stimuli]).update(status=Stimulus.Status.DONE, duration_s=clip_seconds)
    if video is not None:
        for stimulus in stimuli:
            stimulus.video_path().parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(video, stimulus.video_path())
    if is_open:
        study.is_open = True
        study.save(update_fields=["is_open"])
    return study
