"""The researcher's preview: the participant's pages of a study, in order, as a participant
sees them, with nothing recorded.

The pages are the participant's path itself (``participants.path.PATH``): each step says
what it shows in a preview (``Step.preview_pages``: its page where a new participant
meets it, the design's own pages for practice and rating), so a step added to the path is
in the preview too. No participant stands behind them: no one is enrolled, no clip is
reserved, no answer is stored. A banner says it is a preview, and each form leads to the
next page instead of posting (were it posted anyway, no participant cookie goes with it,
so it would change nothing). The pages are in the study's language, as its participants
read them (``participants.language``).
"""

from __future__ import annotations

from dataclasses import dataclass

from django.http import HttpRequest, HttpResponse
from django.shortcuts import render
from django.utils import translation

from studyapp.designs.pages import preview_clip
from studyapp.models import Study
from studyapp.participants import path


@dataclass(frozen=True)
class PreviewPage:
    name: str
    template: str  # under studyapp/templates/studyapp/participant/
    context: dict


def preview_pages(study: Study) -> list[PreviewPage]:
    """The pages a participant of ``study`` meets (empty without a finished clip to rate)."""
    if preview_clip(study) is None:
        return []
    with translation.override(study.language):  # the pages' headings and texts
        return [PreviewPage(step.title or step.name, step.template_for(study), context)
                for step in path.PATH for context in step.preview_pages(study)]


def render_preview(request: HttpRequest, study: Study, page: PreviewPage, preview: dict) -> HttpResponse:
    """``page`` as a participant sees it, in the study's language, under the preview's banner (``preview``)."""
    with translation.override(study.language):
        return render(request, f"studyapp/participant/{page.template}", {"study": study, "preview": preview,
                                                                            **page.context})


__all__ = ["PreviewPage", "preview_pages", "render_preview"]
