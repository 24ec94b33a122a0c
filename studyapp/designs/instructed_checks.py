"""Instructed checks: pages that tell the participant which answer to give.

A study may add ``instructed_checks`` of them to every participant's pages, at random
places after the first. Each repeats one of the participant's rated pages and says, on
the page, what to answer:

- single: "please answer N" (N a random point of the scale; the answer must be N);
- side-by-side: "move the slider of clip X to the far right" (X at random; its value
  must be in the top tenth of the scale);
- pairwise: "please choose clip A" (or B, at random; that answer must be given).

Crowd platforms accept a failed instructed check as grounds for rejecting a submission.
Their answers are kept in the database but never exported (they say nothing about the
motion). A participant who fails ``stop_after_failed_checks`` of them (when set) is
thanked and their session ends.
"""

from __future__ import annotations

import random
from datetime import datetime

from studyapp.designs.page_assignment import PlannedPage
from studyapp.models import Participant, Study

MAX, ANY = "max", "any"  # side-by-side: the clip to push to the top, the others
TOP_SHARE = 0.1  # a side-by-side target passes in the top tenth of the scale


def clip_label(slot: int) -> str:
    """The neutral name of the clip at ``slot`` (1: A; past Z, or a slot a form made up, its number)."""
    return chr(ord("A") + slot - 1) if 1 <= slot <= 26 else str(slot)


def add_instructed_checks(study: Study, pages: list[PlannedPage], rng: random.Random) -> list[PlannedPage]:
    """``pages`` with the study's instructed checks inserted (never first)."""
    rated = [page for page in pages if not page.is_check] or pages
    pages = list(pages)
    for _ in range(study.instructed_checks):
        clips = list(rng.choice(rated).clips)
        if study.design == Study.Design.SINGLE:
            expected = [str(rng.choice(study.scale))]
        elif study.design == Study.Design.SIDE_BY_SIDE:
            target = rng.randrange(len(clips))
            expected = [MAX if i == target else ANY for i in range(len(clips))]
        else:
            expected = [rng.choice(("left", "right"))] * len(clips)
        pages.insert(rng.randint(1, len(pages)), PlannedPage(clips, is_check=True, expected=expected))
    return pages


def instruction(study: Study, expected: list[str]) -> str:
    """What an instructed check's page tells the participant to do ("" on other pages)."""
    if not any(expected):
        return ""
    if study.design == Study.Design.SINGLE:
        return f"Attention check: whatever you think of this clip, please answer {expected[0]}."
    if study.design == Study.Design.SIDE_BY_SIDE:
        label = clip_label(expected.index(MAX) + 1)
        return (f"Attention check: whatever you think of these clips, please move the slider of clip {label} "
                f"to the far right ({study.scale_max}).")
    label = clip_label(1 if expected[0] == "left" else 2)
    return f"Attention check: whatever you think of these clips, please choose clip {label}."


def passed(study: Study, expected: list[str], values: list[int | None], answer: str = "") -> bool:
    """Whether a page's answer (``values`` per clip in slot order, or the pairwise
    ``answer``) is the one its instruction asked for."""
    if study.design == Study.Design.SINGLE:
        return str(values[0]) == expected[0]  # as stored: a changed row asking for no number fails, never crashes
    if study.design == Study.Design.SIDE_BY_SIDE:
        floor = study.scale_max - TOP_SHARE * (study.scale_max - study.scale_min)
        return all(value is not None and value >= floor for want, value in zip(expected, values) if want == MAX)
    return answer == expected[0]


def failure_changes(study: Study, participant: Participant, now: datetime) -> dict:
    """The participant's fields after one more failed check: the count, and the end of
    their session when it reaches the study's limit."""
    failed = participant.failed_checks + 1
    changes: dict = {"failed_checks": failed}
    if study.stop_after_failed_checks and failed >= study.stop_after_failed_checks:
        changes.update(stopped_at=now, finished_at=now)
    return changes
