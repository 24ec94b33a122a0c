"""The single design: one clip a page, rated on the study's scale (MoGlow, HVRNN).

A participant rates ``clips_per_participant`` clips: ``bad_checks`` BAD clips and
``natural_checks`` NAT clips as attention checks, and the rest from every non-BAD
system, least loaded first, among equally loaded ones of the system they have been given
least (so each participant sees the systems evenly), ties broken at random, skipping
stimuli that have reached the study's target. The rated clips are shuffled and the
checks put at random positions. A stimulus's load counts the ratings that will be kept
(not from an excluded participant, not given before the clip ended where early answers
are discarded) plus the clips reserved by participants who are still active.

Practice shows ``training_clips`` clips, one per system in turn with a BAD one first
(so that every participant sees what broken motion looks like), none among the rated
ones. An instructed check asks for a random point of the scale.
"""

from __future__ import annotations

import random
from collections import Counter
from datetime import datetime

import pandas as pd
from django.db.models import Count, Q
from django.http import QueryDict

from analysis.ratings.exclusions import ExclusionRules
from analysis.reports.single_report import Report
from studyapp.designs.answers import client_times
from studyapp.designs.design import (Answer, Design, OnPage, Page, PlannedPage, rated_clip_exclusion)
from studyapp.models import Assignment, Stimulus, Study, System
from studyapp.participants.assignment import active_since
from studyapp.participants.refusal import AnswerRefused


def stimulus_loads(study: Study, cutoff: datetime | None = None) -> Counter:
    """Load of each stimulus of the study (0 where none): kept ratings + reservations of
    participants active since ``cutoff`` (default: those who hold their clips now). Whatever
    its status: a clip being rendered again keeps the answers and reservations it has."""
    cutoff = cutoff or active_since(study)
    kept = Q(rating__isnull=False)
    if study.discard_early:
        kept &= Q(rating__answered_before_end=False)
    held = Q(rating__isnull=True, participant__finished_at__isnull=True, participant__last_seen__gte=cutoff)
    # Counted over the study's assignments, unordered and without joining the stimuli:
    # half the time of a count per stimulus (600 participants), and enrolment's lock waits on it.
    rows = (Assignment.objects.filter(kept | held, participant__study=study, participant__excluded=False)
            .order_by().values("stimulus_id").annotate(load=Count("id")).values_list("stimulus_id", "load"))
    return Counter(dict(rows))


def _least_loaded(candidates: list[Stimulus], loads: Counter, count: int, rng: random.Random,
                  cap: int | None = None, seen: Counter | None = None) -> list[Stimulus]:
    """``count`` of the candidates under ``cap``, least loaded first; among equally loaded
    ones, of the system the participant has been given least so far (``seen``, updated),
    so that one participant sees the systems as evenly as the loads allow."""
    seen = Counter() if seen is None else seen
    load = {s.id: loads[frozenset({s.id})] for s in candidates}
    eligible = [s for s in candidates if cap is None or load[s.id] < cap]
    rng.shuffle(eligible)  # ties at random: min() takes the first
    chosen: list[Stimulus] = []
    while eligible and len(chosen) < count:
        best = min(eligible, key=lambda s: (load[s.id], seen[s.system_id]))
        eligible.remove(best)
        chosen.append(best)
        seen[best.system_id] += 1
    return chosen


MAX_BUTTON_POINTS = 11  # 0-10 at most


class SingleClip(Design):
    template = "clip.html"
    page_word = "Clip"
    count_field = "clips_per_participant"
    form_field = "assignment"
    settings = ("clips_per_participant", "natural_checks")

    def check_pages(self, study: Study) -> int:
        return study.bad_checks + study.natural_checks

    def problems(self, study: Study) -> dict[str, str]:
        if len(study.scale) > MAX_BUTTON_POINTS:  # the page shows a button per point
            return {"scale_max": f"a single-clip page shows a button per point: at most {MAX_BUTTON_POINTS} points, "
                                 f"not {len(study.scale)}"}
        return super().problems(study)

    def loads(self, study: Study, cutoff: datetime) -> Counter:
        return Counter({frozenset({stimulus}): load for stimulus, load in stimulus_loads(study, cutoff).items()})

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        by_role = {role: [s for s in rendered if s.system.role == role] for role in System.Role.values}
        # BAD clips are never analysed, so they have no target; NAT clips are (NAT is a
        # system like the others), so NAT checks too stop at the target.
        seen: Counter = Counter()
        checks = (_least_loaded(by_role[System.Role.BAD], loads, study.bad_checks, rng, seen=seen)
                  + _least_loaded(by_role[System.Role.NATURAL], loads, study.natural_checks, rng,
                                  cap=study.ratings_per_stimulus, seen=seen))
        taken = {s.id for s in checks}
        pool = [s for s in rendered if s.system.role != System.Role.BAD and s.id not in taken]
        rated = _least_loaded(pool, loads, count - len(checks), rng, cap=study.ratings_per_stimulus, seen=seen)
        if not rated:
            return []
        pages = [PlannedPage([s]) for s in rated]
        rng.shuffle(pages)
        for stimulus in checks:
            pages.insert(rng.randint(0, len(pages)), PlannedPage([stimulus], is_check=True))
        return pages

    def practice(self, study: Study, rendered: list[Stimulus], planned: list[PlannedPage],
                 rng: random.Random) -> list[int]:
        rated = {s.id for page in planned for s in page.clips}
        per_system: dict[int, list[int]] = {}
        bad = set()
        for stimulus in rendered:
            if stimulus.id not in rated:
                per_system.setdefault(stimulus.system_id, []).append(stimulus.id)
            if stimulus.system.role == System.Role.BAD:
                bad.add(stimulus.system_id)
        for ids in per_system.values():
            rng.shuffle(ids)
        systems = list(per_system)
        rng.shuffle(systems)
        systems.sort(key=lambda system: system not in bad)  # stable: the shuffle orders the rest
        chosen: list[int] = []
        while len(chosen) < study.training_clips and any(per_system.values()):
            for system in systems:
                if per_system[system] and len(chosen) < study.training_clips:
                    chosen.append(per_system[system].pop())
        rng.shuffle(chosen)  # the BAD example at a random place among them
        return chosen

    def instructed_answer(self, study: Study, clips: list[Stimulus], rng: random.Random) -> list[str]:
        return [str(rng.choice(study.scale))]

    def instruction(self, study: Study, expected: list[str]) -> str:
        return f"Attention check: whatever you think of this clip, please answer {expected[0]}."

    def follows_instruction(self, study: Study, expected: list[str], answer: Answer) -> bool:
        return str(answer.values.get(1)) == expected[0]  # as stored: a changed row asking for no number fails, never crashes

    def page_context(self, study: Study, page: Page) -> dict:
        clip = page.clips[0]
        return {**super().page_context(study, page), "video_url": clip.video_url, "seconds": clip.seconds,
                "scale": list(study.scale), "keys": len(study.scale) <= 10}

    def read_answer(self, study: Study, form: QueryDict) -> Answer:
        text = form.get("value", "")
        try:
            value = int(text)
        except ValueError:
            raise AnswerRefused(f"the rating must be a whole number from {study.scale_min} to {study.scale_max}, "
                                f"not {text[:20]!r}") from None
        return Answer(form.get(self.form_field, ""), {1: client_times(form)}, values={1: value})

    def check_answer(self, study: Study, answer: Answer, slots: list[int]) -> None:
        if answer.values[1] not in study.scale:
            raise AnswerRefused(f"rating {answer.values[1]} is outside the scale {study.scale_min}-{study.scale_max}")

    def exclusion_reason(self, rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
        return rated_clip_exclusion(rules, study, page, answer)

    def report_tables(self, report: Report) -> list[tuple[str, pd.DataFrame]]:
        tables = [("Mean ratings ± 95 % CI (MoGlow Table 2 layout)", report.significance_display),
                  ("Exclusions", report.exclusions),
                  ("One-way ANOVA", report.anova),
                  ("Tukey HSD, all pairs", report.tukey),
                  ("Linear mixed model (participant random intercept)", report.mixed)]
        tables += [(f"Adjusted p-values, {task} · {cc}", m) for (task, cc), m in report.pvalues_display.items()]
        if report.rater_models is not None:  # crossed LMM, cumulative link mixed model, Krippendorff's alpha
            tables += [(title, table) for title, table in report.rater_models.tables().values() if len(table)]
        if report.power is not None and len(report.power):
            tables.append(("Ratings needed for 80 % power per pair", report.power))
        return tables
