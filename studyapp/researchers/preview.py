"""The researcher's preview: the participant's pages of a study, in order, as a participant
sees them, with nothing recorded.

The pages are the path's own templates and contexts (``participant_path``) with no
participant behind them: no one is enrolled, no clip is reserved, no answer is stored. A
banner says it is a preview, and each form leads to the next page instead of posting
(were it posted anyway, no participant cookie goes with it, so it would change nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

from studyapp.models import Participant, Question, Stimulus, Study, System
from studyapp.participants.path import clip_page, completion_page, questions_page


@dataclass(frozen=True)
class PreviewPage:
    name: str
    template: str  # under studyapp/templates/studyapp/participant/
    context: dict


def preview_pages(study: Study) -> list[PreviewPage]:
    """The pages a participant of ``study`` meets, with a finished clip of a rated system
    standing for every clip (empty when there is none yet)."""
    clip = (Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE)
            .exclude(system__role=System.Role.BAD).order_by("pk").first())
    if clip is None:
        return []
    nobody = Participant(study=study)  # unsaved: it only lets the completion page say where to go
    parts = set(study.questions.values_list("part", flat=True))
    pages = []
    if study.device_check:
        pages.append(PreviewPage("device check", "device.html", {
            "video_url": clip.video_url, "min_width": study.min_screen_width, "min_height": study.min_screen_height}))
    pages.append(PreviewPage("consent", "consent.html", {}))
    if Question.Part.BEFORE in parts:
        pages.append(PreviewPage("screening", "questions.html", questions_page(Question.Part.BEFORE)(study, nobody)))
    pages.append(PreviewPage("instructions", "instructions.html", {}))
    total = study.clips_per_participant
    pages.append(PreviewPage("a clip to rate", "clip.html", clip_page(
        study, clip, "participant-rate", {"assignment": "preview"}, f"Clip 1 of {total}", 0, total, None)))
    if Question.Part.AFTER in parts:
        pages.append(PreviewPage("closing questions", "questions.html", questions_page(Question.Part.AFTER)(study, nobody)))
    pages.append(PreviewPage("completion", "done.html", completion_page(study, nobody)))
    return pages


__all__ = ["PreviewPage", "preview_pages"]
