"""The side-by-side design: every system's clip of one control on a page, each rated on a
slider (HEMVIP / MUSHRA, as in the GENEA challenges; 0-100 unless the study sets a scale).

A participant answers ``pages_per_participant`` controls' pages; every system with a clip
of the control is on its page (NAT as a hidden reference), and a BAD clip joins
``bad_checks`` of them as an anchor. The order on a page is the next row of a Williams
design (``williams_row``), so positions and neighbours are counterbalanced. The study's
thresholds, rescaled to its scale, apply to every clip as in the single design (on 0-100
with the defaults: a NAT clip below 25 or a BAD clip at 75 or above excludes the
participant, as GENEA does). An instructed check asks for one clip's slider at the top
(its value in the top tenth of the scale). Practice shows pages of this kind too, about
``training_clips`` clips in whole pages, of controls the participant does not rate.

With the study's ``sliders_must_move`` (as webMUSHRA offers; on for a new study) every
slider starts in the middle of the scale and the answer is taken only once each has been
moved. The page's script says so in a hidden field per slider (``moved-<slot>``, set at
the slider's first move, even one back to the middle); a browser without scripts cannot
tell, so there a value other than the starting one counts as moved.
"""

from __future__ import annotations

import random
import re
from collections import Counter

import pandas as pd
from django.http import QueryDict

from analysis.ratings.exclusions import ExclusionRules
from analysis.stats.within_page import median_and_mean
from studyapp.designs.answers import whole_number
from studyapp.designs.design import (Answer, OnPage, Page, PlannedPage, clip_label, rated_clip_exclusion)
from studyapp.designs.multi_clip import MultiClip, bad_for, by_control, key_of, page_orders
from studyapp.designs.reasons import check_reasons, read_reasons, reasons_context
from studyapp.models import Assignment, Rating, Stimulus, Study, System
from studyapp.participants.refusal import AnswerRefused

MAX, ANY = "max", "any"  # an instructed check: the clip to push to the top, the others
TOP_SHARE = 0.1  # an instructed check passes in the top tenth of the scale
SLOT_FIELD = re.compile(r"value-[0-9]{1,18}")


def williams_row(k: int, row: int) -> list[int]:
    """Row ``row`` of a Williams design for ``k`` clips: the order of the clips' indices.

    Every k consecutive rows (2k when k is odd: the square, then its mirror) put each clip
    at each position once, and after each other clip equally often, so neither position
    nor the clip seen just before favours any system.
    """
    first, low, high = [0], 1, k - 1
    while len(first) < k:
        first.append(low)
        low += 1
        if len(first) < k:
            first.append(high)
            high -= 1
    order = [(index + row) % k for index in first]
    return order[::-1] if k % 2 and (row // k) % 2 else order


def _williams_order(clips: list[Stimulus], orders: Counter, offset: int) -> list[Stimulus]:
    """The clips in slot order: the page's next row of its Williams design (rows counted
    from ``offset``, once per earlier hand-out of the same clips); ``orders`` is updated."""
    clips = sorted(clips, key=lambda s: s.id)
    ids = {s.id for s in clips}
    handed_out = sum(n for (_, order), n in orders.items() if set(order) == ids)
    order = [clips[i] for i in williams_row(len(clips), handed_out + offset)]
    orders[key_of(order), tuple(s.id for s in order)] += 1
    return order


class SideBySide(MultiClip):
    template = "side_by_side.html"
    default_scale = (0, 100)
    settings = ("pages_per_participant", "sliders_must_move", "reasons", "reasons_required")
    export_columns = ("design", "page", "position")

    def clips_per_page(self, study: Study) -> float:
        """Every rated system's clip, and a BAD anchor on ``bad_checks`` of the pages."""
        systems = study.systems.exclude(role=System.Role.BAD).count()
        anchors = min(study.bad_checks, study.pages_per_participant) if study.systems.filter(
            role=System.Role.BAD).exists() else 0
        return max(systems + anchors / max(study.pages_per_participant, 1), 1.0)

    def answers_per_page(self, study: Study) -> float:
        return self.clips_per_page(study)  # a slider each

    def _pages_with_anchor(self, study: Study, controls: list[list[Stimulus]], bad: dict, anchors: int,
                           rng: random.Random, orders: Counter) -> list[PlannedPage]:
        """A page per control, a BAD anchor on the first ``anchors`` of them, each in its Williams order."""
        planned = []
        for index, page in enumerate(controls):
            anchor = bad_for(page[0].control_id, bad, rng) if index < anchors else None
            # Each control's design starts at a row of its own, fixed for the study, so that
            # the first participants do not all see the same order on every page.
            offset = random.Random(f"{study.key}:{page[0].control_id}").randrange(2 * len(page) + 2)
            planned.append(PlannedPage(_williams_order(page + ([anchor] if anchor else []), orders, offset),
                                       is_check=anchor is not None))
        return planned

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        clips, bad = by_control(rendered)
        pages = [page for page in clips.values() if len(page) >= 2]
        rng.shuffle(pages)  # ties at random: sort() is stable
        pages.sort(key=lambda page: loads[key_of(page)])
        chosen = [page for page in pages if loads[key_of(page)] < study.ratings_per_stimulus][:count]
        planned = self._pages_with_anchor(study, chosen, bad, study.bad_checks, rng, page_orders(study))
        rng.shuffle(planned)
        return planned

    def practice(self, study: Study, rendered: list[Stimulus], planned: list[PlannedPage],
                 rng: random.Random) -> list[int]:
        clips, bad = by_control(rendered)
        rated = {s.control_id for page in planned for s in page.clips}
        pages = [page for control, page in clips.items() if len(page) >= 2]
        rng.shuffle(pages)
        pages.sort(key=lambda page: page[0].control_id in rated)  # controls the participant does not rate first
        chosen = pages[:self.practice_page_count(study)]
        # With a BAD anchor, as the rated pages have, so that practice shows broken motion too.
        practice = self._pages_with_anchor(study, chosen, bad, len(chosen), rng, Counter())
        return [s.id for page in practice for s in page.clips]

    def practice_pages(self, clips: list[Stimulus]) -> list[list[Stimulus]]:
        """Runs of one control's clips (a BAD anchor that is an uploaded video joins the run it is in)."""
        pages: list[list[Stimulus]] = []
        for clip in clips:
            control = next((c.control_id for c in pages[-1] if c.control_id is not None), None) if pages else None
            if pages and clip.control_id in (control, None):
                pages[-1].append(clip)
            else:
                pages.append([clip])
        return pages

    def instructed_answer(self, study: Study, clips: list[Stimulus], rng: random.Random) -> list[str]:
        target = rng.randrange(len(clips))
        return [MAX if i == target else ANY for i in range(len(clips))]

    def instruction(self, study: Study, expected: list[str]) -> str:
        label = clip_label(expected.index(MAX) + 1)
        return (f"Attention check: whatever you think of these clips, please move the slider of clip {label} "
                f"to the far right ({study.scale_max}).")

    def follows_instruction(self, study: Study, expected: list[str], answer: Answer) -> bool:
        floor = study.scale_max - TOP_SHARE * (study.scale_max - study.scale_min)
        return all((value := answer.values.get(slot)) is not None and value >= floor
                   for slot, want in enumerate(expected, start=1) if want == MAX)

    @staticmethod
    def middle(study: Study) -> int:
        """Where every slider starts."""
        return (study.scale_min + study.scale_max) // 2

    def page_context(self, study: Study, page: Page) -> dict:
        return {**super().page_context(study, page), "middle": self.middle(study), **reasons_context(study)}

    def task(self, study: Study) -> str:
        moved = " Move every slider before you answer." if study.sliders_must_move else ""
        return (f"Each page shows several clips side by side. {study.question} Rate each clip on its slider, from "
                f"{study.scale_min} ({study.label_min}) to {study.scale_max} ({study.label_max}).{moved}")

    def read_answer(self, study: Study, form: QueryDict) -> Answer:
        # A slot is ASCII digits: "²" passes isdigit() but not int(), nor do 5000 digits (a made-up slot of 18 is refused).
        slots = sorted({int(name.removeprefix("value-")) for name in form if SLOT_FIELD.fullmatch(name)})
        values = {}
        for slot in slots:
            value = whole_number(form, f"value-{slot}", f"the rating of clip {clip_label(slot)}")
            if value is None:
                raise AnswerRefused(f"clip {clip_label(slot)} has no rating")
            values[slot] = value
        moved = frozenset(slot for slot, value in values.items()
                          if form.get(f"moved-{slot}") == "1" or value != self.middle(study))
        reasons, other = read_reasons(study, form)
        return Answer(form.get(self.form_field, ""), self.slot_times(form, slots), values=values, moved=moved,
                      reasons=reasons, other_reason=other)

    def check_answer(self, study: Study, answer: Answer, slots: list[int]) -> None:
        for slot, value in answer.values.items():
            if value not in study.scale:
                raise AnswerRefused(f"the rating of clip {clip_label(slot)} ({value}) is outside the scale "
                                    f"{study.scale_min}-{study.scale_max}")
        if set(answer.values) != set(slots):
            missing = sorted(set(slots) - set(answer.values))
            raise AnswerRefused(f"every clip on the page needs a rating; missing: clip "
                                f"{', '.join(map(clip_label, missing))}" if missing
                                else "ratings were sent for clips that are not on this page")
        if study.sliders_must_move and (unmoved := sorted(set(slots) - answer.moved)):
            raise AnswerRefused(f"please move each clip's slider before you answer; not moved: the slider of clip "
                                f"{', '.join(map(clip_label, unmoved))}")
        check_reasons(study, answer.reasons, answer.other_reason)

    def exclusion_reason(self, rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
        return rated_clip_exclusion(rules, study, page, answer)

    def export_fields(self, assignment: Assignment, rating: Rating) -> dict:
        return {"design": self.name, "page": assignment.page + 1, "position": assignment.slot}

    def monitor_tables(self, compared: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
        return [("Median and mean per system (95 % CIs)", median_and_mean(compared))]

