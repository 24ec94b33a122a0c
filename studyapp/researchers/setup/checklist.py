"""The researcher's checklist of a study, in order, with what each item has and lacks:

    settings -> systems -> controls -> stimuli -> preview -> open

Every study page shows it at its top, so a researcher always sees what is left to do; the
preview is ticked once the researcher has seen it (``Study.previewed_at``).
The settings' card also says how long a participant is expected to take (``duration``).
"""

from __future__ import annotations

from dataclasses import dataclass

from django.db.models import Count, Q
from django.urls import reverse

from studyapp.designs.registry import design_of
from studyapp.models import Stimulus, Study, System
from studyapp.researchers.setup.duration import expected_duration
from studyapp.researchers.setup.readiness import open_problems, open_warnings


@dataclass(frozen=True)
class ChecklistItem:
    name: str
    url: str
    done: bool
    note: str  # what it has, or what it lacks


def checklist(study: Study) -> list[ChecklistItem]:
    systems = study.systems.aggregate(models=Count("pk", filter=Q(role=System.Role.MODEL)), all=Count("pk"))
    controls = study.controls.count()
    stimuli = study.stimuli.aggregate(all=Count("pk"), done=Count("pk", filter=Q(status=Stimulus.Status.DONE)),
                                      failed=Count("pk", filter=Q(status=Stimulus.Status.FAILED)))
    problems = open_problems(study)
    previewed = study.previewed_at is not None and stimuli["done"] > 0

    def url(name: str) -> str:
        return reverse(f"study-{name}", args=[study.pk])

    stimuli_note = (f"{stimuli['done']} of {stimuli['all']} clips finished"
                    + (f", {stimuli['failed']} failed" if stimuli["failed"] else "")) if stimuli["all"] else "none generated"
    return [
        ChecklistItem("Settings", url("edit"), True, _settings_note(study)),
        ChecklistItem("Systems", url("systems"), systems["models"] > 0,
                  f"{systems['all']} system(s)" if systems["models"] else "no model system yet"),
        ChecklistItem("Controls", url("controls"), controls > 0, f"{controls} control(s)" if controls else "none yet"),
        ChecklistItem("Stimuli", url("stimuli"), stimuli["all"] > 0 and stimuli["done"] == stimuli["all"], stimuli_note),
        ChecklistItem("Preview", url("preview"), previewed,
                  "seen" if previewed else "see the pages as a participant" if stimuli["done"] else "needs a finished clip"),
        ChecklistItem("Open", url("monitor"), study.is_open,
                  "open" if study.is_open else problems[0] if problems else
                  "ready to open, with a warning" if open_warnings(study) else "ready to open"),
    ]


def _settings_note(study: Study) -> str:
    """The platform, the scale (where answers are on one), and the time to advertise and how it was reckoned."""
    note = study.get_platform_display()
    if design_of(study).on_scale:
        note += f", scale {study.scale_min}–{study.scale_max}"
    duration = expected_duration(study)
    if duration is not None:
        note += f"; advertise about {duration.minutes} min ({duration.how})"
    return note


__all__ = ["ChecklistItem", "checklist"]
