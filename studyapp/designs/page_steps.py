"""The pages of the side-by-side and pairwise designs: what each shows and what its form does.

``participant_path.PATH`` lists them as steps of their design. A page names its clips
by neutral letters (A, B, ...) in their slot order, which the assignment randomised and
counterbalanced; its form names the page by its first clip's random token and each clip
by its slot, so nothing on it says which system made which clip.
"""

from __future__ import annotations

import re

from django.db.models import Count, Q
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect
from django.utils import timezone

from studyapp.designs.instructed_checks import clip_label, instruction
from studyapp.designs.page_ratings import PageAnswer, current_page, record_page
from studyapp.designs.ratings import ClientTimes, RatingRejected
from studyapp.models import Assignment, Participant, Stimulus, Study, System

TIME_FIELDS = ("started_s", "ended_s", "answered_s", "played_until_s")
SLOT_FIELD = re.compile(r"value-[0-9]{1,4}")


def optional_seconds(request: HttpRequest, name: str) -> float | None:
    """A client time in seconds from the posted form, None when empty."""
    text = request.POST.get(name, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise RatingRejected(f"{name} must be a number of seconds, not {text[:20]!r}") from None
    if not 0 <= value < 1e6:
        raise RatingRejected(f"{name} must lie between 0 and a million seconds, not {value}")
    return value


def client_times(request: HttpRequest, suffix: str = "") -> ClientTimes:
    """The browser's times of one clip (fields ``started_s<suffix>``, ...)."""
    return ClientTimes(*(optional_seconds(request, f"{name}{suffix}") for name in TIME_FIELDS))


def _whole_number(request: HttpRequest, name: str, what: str) -> int | None:
    text = request.POST.get(name, "").strip()
    if not text:
        return None
    try:
        return int(text)
    except ValueError:
        raise RatingRejected(f"{what} must be a whole number, not {text[:20]!r}") from None


def page_context(study: Study, participant: Participant) -> dict:
    """The clips of the current page (marked as shown), their labels, the progress and any instruction."""
    page = current_page(participant)
    unshown = [a.pk for a in page if a.shown_at is None]
    if unshown:
        Assignment.objects.filter(pk__in=unshown).update(shown_at=timezone.now())
    counts = participant.assignments.aggregate(total=Count("page", distinct=True),
                                               left=Count("page", distinct=True, filter=Q(rating__isnull=True)))
    total, done = counts["total"], counts["total"] - counts["left"]
    return {
        "clips": [{"slot": a.slot, "label": clip_label(a.slot), "video_url": a.stimulus.video_url,
                   "seconds": a.stimulus.duration_s or 0.0} for a in page],
        "form": {"page": page[0].token}, "heading": f"Page {done + 1} of {total}", "done": done, "total": total,
        "percent": round(100 * done / total) if total else 100,
        "instruction": instruction(study, [a.expected for a in page]),
        "middle": (study.scale_min + study.scale_max) // 2,  # where every slider starts
        "strengths": list(study.strengths), "time_fields": TIME_FIELDS, "reference": _reference(study, page),
    }


def _reference(study: Study, page: list[Assignment]) -> dict | None:
    """ABX: the page's reference X, the natural clip of its control (played like the others, not rated)."""
    if not study.abx:
        return None
    natural = Stimulus.objects.filter(study=study, control_id=page[0].stimulus.control_id, status=Stimulus.Status.DONE,
                                      system__role=System.Role.NATURAL).first()
    return {"video_url": natural.video_url} if natural else None


def rate_side_by_side(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Store the sliders of the page on screen."""
    # A slot is a few ASCII digits: "²" passes isdigit() but not int(), and 5000 digits pass neither limit.
    slots = sorted({int(name.removeprefix("value-")) for name in request.POST if SLOT_FIELD.fullmatch(name)})
    values = {}
    for slot in slots:
        value = _whole_number(request, f"value-{slot}", f"the rating of clip {clip_label(slot)}")
        if value is None:
            raise RatingRejected(f"clip {clip_label(slot)} has no rating")
        values[slot] = value
    times = {slot: client_times(request, f"-{slot}") for slot in slots}
    record_page(participant, request.POST.get("page", ""), PageAnswer(times, values=values))
    return redirect("participant-page", key=study.key)


def rate_pairwise(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Store the preference of the page on screen."""
    times = {slot: client_times(request, f"-{slot}") for slot in (Assignment.LEFT, Assignment.RIGHT)}
    answer = PageAnswer(times, answer=request.POST.get("answer", "").strip(),
                        strength=_whole_number(request, "strength", "the strength of the preference"))
    record_page(participant, request.POST.get("page", ""), answer)
    return redirect("participant-page", key=study.key)
