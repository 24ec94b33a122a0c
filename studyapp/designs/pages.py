"""The pages of a participant's path that show clips, in every design: the rating page
on screen, the practice pages before it, and what the preview shows of both.

Each is a ``base.Page`` (its clips, form and progress) that the study's design turns
into its template's context. A rating page is the first page with an unrated clip (read
with the participant's other clips in one query: the next page's clips are fetched while
these play, and all of them make the progress); a practice page is the next group of
the participant's practice clips in the design's own page (``Design.practice_pages``),
answered as a rated page is, and not recorded.
"""

from __future__ import annotations

import random
from collections import Counter

from django.http import Http404
from django.utils import timezone

from studyapp.designs.design import Page, PageClip, PlannedPage
from studyapp.designs.registry import design_of
from studyapp.models import Assignment, Participant, Stimulus, Study, System
from studyapp.server.db.compiled_queries import CompiledQuery


def _video_url(token: str) -> str:
    return Stimulus(token=token).video_url


# Every clip of a participant, in order, with what their pages show.
_clips_in_order = CompiledQuery(
    lambda participant: Assignment.objects.filter(participant_id=participant).order_by("position").values(
        "pk", "token", "page", "slot", "shown_at", "expected", "rating", "stimulus__token",
        "stimulus__duration_s", "stimulus__control_id", "stimulus__shown_control_id"), int)


def rating_page(study: Study, participant: Participant) -> dict:
    """The context of the participant's page on screen (marked as shown, if it was not)."""
    design = design_of(study)
    pages: dict[int, list[dict]] = {}
    for clip in _clips_in_order(participant.pk):
        pages.setdefault(clip["page"], []).append(clip)
    unrated = [page for page in pages.values() if any(clip["rating"] is None for clip in page)]
    current, upcoming = unrated[0], unrated[1] if len(unrated) > 1 else []
    if unshown := [clip["pk"] for clip in current if clip["shown_at"] is None]:
        # The first page, or one after a return: an answer marks the page after it.
        Assignment.objects.filter(pk__in=unshown).update(shown_at=timezone.now())
    done = len(pages) - len(unrated)
    page = Page(
        clips=[PageClip(clip["slot"], clip["token"], _video_url(clip["stimulus__token"]),
                        clip["stimulus__duration_s"] or 0.0, clip["stimulus__control_id"], clip["expected"],
                        clip["stimulus__shown_control_id"])
               for clip in sorted(current, key=lambda clip: clip["slot"])],
        action="participant-rate", form={design.form_field: current[0]["token"]},
        heading=f"{design.page_word} {done + 1} of {len(pages)}", done=done, total=len(pages),
        upcoming=[_video_url(clip["stimulus__token"]) for clip in upcoming])
    return design.page_context(study, page)


def _practice_clips(study: Study, participant: Participant) -> list[Stimulus]:
    ids = participant.practice_ids()
    stimuli = Stimulus.objects.in_bulk(ids)
    if any(pk not in stimuli for pk in ids):
        raise Http404("practice clip gone")
    return [stimuli[pk] for pk in ids]


def remaining_practice(study: Study, participant: Participant) -> list[list[Stimulus]]:
    """The participant's practice pages not yet passed, in order."""
    return design_of(study).practice_pages(_practice_clips(study, participant)[participant.training_done:])


def _clips_context(study: Study, clips: list[Stimulus], action: str, form: dict, heading: str, done: int,
                   total: int, upcoming: list[Stimulus]) -> dict:
    """The design's context of a page of ``clips`` that no assignment stands behind (practice, preview)."""
    page = Page(clips=[PageClip(slot, "", clip.video_url, clip.duration_s or 0.0, clip.control_id,
                                shown_control_id=clip.shown_control_id)
                       for slot, clip in enumerate(clips, start=1)],
                action=action, form=form, heading=heading, done=done, total=total,
                upcoming=[clip.video_url for clip in upcoming])
    return design_of(study).page_context(study, page)


def practice_context(study: Study, pages: list[list[Stimulus]], done: int, total: int, index: int) -> dict:
    """The context of practice page ``pages[0]`` (``done`` of ``total`` passed), its form naming ``index``."""
    return _clips_context(study, pages[0], "participant-practice", {"index": str(index)},
                          f"Practice {design_of(study).page_word.lower()} {done + 1} of {total} (not recorded)",
                          done, total, pages[1] if len(pages) > 1 else [])


def practice_page(study: Study, participant: Participant) -> dict:
    """The context of the participant's next practice page."""
    design = design_of(study)
    clips = _practice_clips(study, participant)
    remaining = design.practice_pages(clips[participant.training_done:])
    total = len(design.practice_pages(clips))
    return practice_context(study, remaining, max(total - len(remaining), 0), total, participant.training_done)


def _preview_plan(study: Study) -> tuple[list[PlannedPage], list[list[Stimulus]]]:
    """A participant's pages and practice pages as the design plans them now (none without
    a finished clip to rate); nothing is stored or reserved."""
    design = design_of(study)
    rendered = list(Stimulus.objects.filter(study=study, status=Stimulus.Status.DONE).select_related("system"))
    if not any(s.system.role != System.Role.BAD for s in rendered):
        return [], []
    rng = random.Random(0)
    planned = design.plan(study, rendered, Counter(), design.page_count(study), rng)
    by_id = {s.id: s for s in rendered}
    return planned, design.practice_pages([by_id[pk] for pk in design.practice(study, rendered, planned, rng)])


def preview_rating_pages(study: Study) -> list[dict]:
    """A rated page of the study as its participants will see it (none without finished clips)."""
    planned, _ = _preview_plan(study)
    if not planned:
        return []
    design = design_of(study)
    page = next((page for page in planned if not page.is_check), planned[0])
    total = design.page_count(study)
    return [_clips_context(study, page.clips, "participant-rate", {design.form_field: "preview"},
                           f"{design.page_word} 1 of {total}", 0, total, [])]


def preview_practice_pages(study: Study) -> list[dict]:
    """The first practice page of the study (none without practice)."""
    _, practice = _preview_plan(study)
    return [practice_context(study, practice, 0, len(practice), 0)] if practice else []


def preview_clip(study: Study) -> Stimulus | None:
    """A clip a participant of the study would see (none: nothing to preview yet)."""
    planned, _ = _preview_plan(study)
    return planned[0].clips[0] if planned else None
