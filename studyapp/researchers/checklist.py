"""The researcher's steps through a study, in order, with what each has and lacks:

    settings -> systems -> controls -> stimuli -> preview -> open

Every study page shows them at its top, so a researcher always sees what is left to do.
"""

from __future__ import annotations

from dataclasses import dataclass

from django.db.models import Count, Q
from django.urls import reverse

from studyapp.models import Stimulus, Study, System
from studyapp.designs.registry import design_of
from studyapp.researchers.readiness import open_problems, open_warnings


@dataclass(frozen=True)
class StudyStep:
    name: str
    url: str
    done: bool
    note: str  # what it has, or what it lacks


def study_steps(study: Study) -> list[StudyStep]:
    systems = study.systems.aggregate(models=Count("pk", filter=Q(role=System.Role.MODEL)), all=Count("pk"))
    controls = study.controls.count()
    stimuli = study.stimuli.aggregate(all=Count("pk"), done=Count("pk", filter=Q(status=Stimulus.Status.DONE)),
                                      failed=Count("pk", filter=Q(status=Stimulus.Status.FAILED)))
    problems = open_problems(study)
    previewed = study.previewed_at is not None and stimuli["done"] > 0

    def url(name: str) -> str:
        return reverse(f"study-{name}", args=[study.pk])

    design = design_of(study)
    shown = f"scale {study.scale_min}–{study.scale_max}" if design.on_scale else \
        f"{design.name}{' with ABX' if study.abx else ''}, no scale"
    stimuli_note = (f"{stimuli['done']} of {stimuli['all']} clips finished"
                    + (f", {stimuli['failed']} failed" if stimuli["failed"] else "")) if stimuli["all"] else "none generated"
    return [
        StudyStep("Settings", url("edit"), True, f"{study.get_platform_display()}, {shown}"),
        StudyStep("Systems", url("systems"), systems["models"] > 0,
                  f"{systems['all']} system(s)" if systems["models"] else "no model system yet"),
        StudyStep("Controls", url("controls"), controls > 0, f"{controls} control(s)" if controls else "none yet"),
        StudyStep("Stimuli", url("stimuli"), stimuli["all"] > 0 and stimuli["done"] == stimuli["all"], stimuli_note),
        StudyStep("Preview", url("preview"), previewed,
                  "seen" if previewed else "see the pages as a participant" if stimuli["done"] else "needs a finished clip"),
        StudyStep("Open", url("monitor"), study.is_open,
                  "open" if study.is_open else problems[0] if problems else
                  "ready to open, with a warning" if open_warnings(study) else "ready to open"),
    ]


__all__ = ["StudyStep", "study_steps"]
