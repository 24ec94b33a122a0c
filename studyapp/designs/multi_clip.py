"""What the designs with several clips on a page share (side by side, pairwise).

A page is identified by its content: the ids of its non-BAD clips (``PageKey``). Its load
counts the participants who answered it and are kept (not excluded, no clip of it
answered before its end where early answers are discarded) plus those who hold it while
still active; pages are handed out least loaded first and never past
``ratings_per_stimulus``. A page names its clips by neutral letters (A, B, ...) in their
slot order, which the plan randomised and counterbalanced; its form names the page by its
first clip's random token and each clip's times by its slot, so nothing on it says which
system made which clip.
"""

from __future__ import annotations

import random
from collections import Counter, defaultdict
from datetime import datetime

import pandas as pd
from django.http import QueryDict

from analysis.reports.design_report import DesignReport
from studyapp.designs.answers import client_times
from studyapp.designs.design import Design, PageKey
from studyapp.models import Assignment, Stimulus, Study, System


def page_loads(study: Study, cutoff: datetime) -> Counter:
    """Load of each page content (``PageKey``): kept answered pages plus pages held by
    participants active since ``cutoff``. Instructed checks repeat other pages and do not count."""
    rows = (Assignment.objects.filter(participant__study=study, participant__excluded=False, expected="")
            .order_by()  # grouped below: no joins to sort by
            .values_list("participant_id", "page", "stimulus_id", "stimulus__system__role", "rating__id",
                         "rating__answered_before_end", "participant__finished_at", "participant__last_seen"))
    pages: dict[tuple[int, int], list[tuple]] = defaultdict(list)
    for participant, page, *rest in rows:
        pages[participant, page].append(tuple(rest))
    loads: Counter = Counter()
    for clips in pages.values():
        if all(_counted(study, cutoff, *clip[2:]) for clip in clips):
            loads[frozenset(stimulus for stimulus, role, *_ in clips if role != System.Role.BAD)] += 1
    return loads


def _counted(study: Study, cutoff: datetime, rating: int | None, early: bool | None, finished: datetime | None,
             last_seen: datetime) -> bool:
    if rating is not None:
        return not (study.discard_early and early)
    return finished is None and last_seen >= cutoff


def page_orders(study: Study) -> Counter:
    """How often each page content has been handed out in each order: (PageKey, stimulus
    ids in slot order) -> count, over every participant (answered, held or released)."""
    rows = (Assignment.objects.filter(participant__study=study, expected="")
            .values_list("participant_id", "page", "slot", "stimulus_id", "stimulus__system__role"))
    pages: dict[tuple[int, int], list[tuple[int, int, str]]] = defaultdict(list)
    for participant, page, slot, stimulus, role in rows:
        pages[participant, page].append((slot, stimulus, role))
    orders: Counter = Counter()
    for clips in pages.values():
        clips.sort()
        key = frozenset(stimulus for _, stimulus, role in clips if role != System.Role.BAD)
        orders[key, tuple(stimulus for _, stimulus, _ in clips)] += 1
    return orders


def by_control(rendered: list[Stimulus]) -> tuple[dict[int, list[Stimulus]], dict[int | None, list[Stimulus]]]:
    """Non-BAD clips per control (one per system: the first rendered) and BAD clips per
    control (None: uploaded BAD videos, which can join any page). Mismatched clips (made
    for another control than the one they are shown with) are no control's clip."""
    clips: dict[int, dict[int, Stimulus]] = defaultdict(dict)
    bad: dict[int | None, list[Stimulus]] = defaultdict(list)
    for stimulus in sorted(rendered, key=lambda s: s.id):
        if stimulus.shown_control_id is not None:
            continue
        if stimulus.system.role == System.Role.BAD:
            bad[stimulus.control_id].append(stimulus)
        elif stimulus.control_id is not None:
            clips[stimulus.control_id].setdefault(stimulus.system_id, stimulus)
    return {control: list(systems.values()) for control, systems in clips.items()}, bad


def bad_for(control: int, bad: dict[int | None, list[Stimulus]], rng: random.Random) -> Stimulus | None:
    """A BAD clip for a page of ``control``: its own if it has one, else an uploaded one."""
    candidates = bad.get(control) or bad.get(None) or []
    return rng.choice(candidates) if candidates else None


def key_of(clips: list[Stimulus]) -> PageKey:
    return frozenset(s.id for s in clips if s.system.role != System.Role.BAD)


class MultiClip(Design):
    """The part of the side-by-side and pairwise designs that is the same."""

    def loads(self, study: Study, cutoff: datetime) -> Counter:
        return page_loads(study, cutoff)

    def slot_times(self, form: QueryDict, slots: list[int]) -> dict:
        """Each clip's times, from the fields ``started_s-<slot>``, ..."""
        return {slot: client_times(form, f"-{slot}") for slot in slots}

    def report_tables(self, report: DesignReport) -> list[tuple[str, pd.DataFrame]]:
        return [("Exclusions", report.exclusions), *((title, table) for title, table in report.tables.values()
                                                     if len(table))]
