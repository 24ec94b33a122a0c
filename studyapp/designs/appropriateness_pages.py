"""The appropriateness design: does a system's motion fit the control it was made for?

A page shows one system twice, as the GENEA challenges do with mismatched stimuli: its
clip made for the page's control and its clip made for that control's partner
(``stimuli.mismatched``: ``generation.mismatch``'s rule, the same partner for every
system), both drawn over the page's control's path with the camera following it (for a
label control, the page names the action and style in words). Which fits the shown
control better, on five levels: either clip clearly or slightly better, or no difference
(``answer`` and a ``strength`` of 1 or 2, docs/ratings-schema.md). Sides are balanced:
each pair is shown in the order it has been shown less often.

A participant answers ``pages_per_participant`` pages: ``bad_checks`` attention checks,
NAT's clip of a held-out control beside another take that obviously does not follow it
(the rule's attention partner, where that is not the control's partner already: a check
never repeats a rated page; preferring that take excludes the participant), and the
rest from every system's pairs, least loaded first, among them the systems and controls
this participant has seen least. In the ratings table a check page's rows name their
system BAD, as the analysis expects (``analysis.stats.matching``). Practice shows pairs
too, an attention check's among them, none that the participant rates.
"""

from __future__ import annotations

import random
from collections import Counter

import pandas as pd
from django.db.models import QuerySet

from analysis.stats.matching import appropriateness_scores, matched_preference
from analysis.ratings.exclusions import ExclusionRules
from studyapp.designs.design import Answer, OnPage, Page, PlannedPage
from studyapp.designs.multi_clip import key_of, page_orders
from studyapp.designs.pairwise_pages import SIDES, Pairwise, balanced_sides
from studyapp.models import ATTENTION_NAME, Assignment, ControlSignal, Rating, Stimulus, Study, System
from studyapp.stimuli.mismatched import study_pairings

Pair = tuple[Stimulus, Stimulus]  # (matched, mismatched): a system's clips of a page, before sides are chosen
STRENGTHS = 2  # GENEA's five levels: slightly or clearly better, either way, or no difference


class Appropriateness(Pairwise):
    template = "appropriateness.html"
    settings = ("pages_per_participant",)
    export_columns = ("design", "page", "side", "matched", "answer", "strength", "shown_control", "made_for")
    mismatched_clips = True
    power_table = False  # its systems are not compared on shared pages: the scores' intervals say it
    attention_check_role = System.Role.NATURAL

    def strengths(self, study: Study) -> range:
        return range(1, STRENGTHS + 1)

    def clips_per_page(self, study: Study) -> float:
        return 2.0

    def _pairs(self, study: Study, rendered: list[Stimulus]) -> tuple[list[Pair], list[Pair]]:
        """The (matched, mismatched) clips of rated pages and of NAT's attention checks,
        by the controls' current pairings, where both clips are rendered."""
        pairings = {pairing.shown.pk: pairing for pairing in study_pairings(study)}
        clips: dict[tuple, Stimulus] = {}
        for stimulus in sorted(rendered, key=lambda s: s.id):
            if stimulus.system.role != System.Role.BAD and stimulus.control_id is not None:
                clips.setdefault((stimulus.system_id, stimulus.control_id, stimulus.shown_control_id), stimulus)
        rated, checks = [], []
        for (system, control, shown), matched in clips.items():
            pairing = pairings.get(control)
            if shown is not None or pairing is None:
                continue
            if pairing.partner and (mismatched := clips.get((system, pairing.partner.pk, control))):
                rated.append((matched, mismatched))
            if matched.system.role == System.Role.NATURAL and pairing.checked_with and (
                    wrong := clips.get((system, pairing.checked_with.pk, control))):
                checks.append((matched, wrong))
        return rated, checks

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        rated, checks = self._pairs(study, rendered)
        orders = page_orders(study)
        rng.shuffle(checks)
        check_pages = [PlannedPage(balanced_sides(pair, orders, rng), is_check=True)
                       for pair in checks[:study.bad_checks]]
        pairs = [pair for pair in rated if loads[key_of(list(pair))] < study.ratings_per_stimulus]
        rng.shuffle(pairs)  # ties at random: min() takes the first
        systems: Counter = Counter()  # on this participant's rated pages
        controls: Counter = Counter()
        pages = []
        while pairs and len(pages) + len(check_pages) < count:
            pair = min(pairs, key=lambda p: (loads[key_of(list(p))], systems[p[0].system_id], controls[p[0].control_id]))
            pairs.remove(pair)
            systems[pair[0].system_id] += 1
            controls[pair[0].control_id] += 1
            pages.append(PlannedPage(balanced_sides(pair, orders, rng)))
        if not pages:
            return []
        for check in check_pages:
            pages.insert(rng.randint(0, len(pages)), check)
        return pages

    def makes_attention_checks(self, study: Study, finished: QuerySet[Stimulus]) -> bool:
        return bool(self._pairs(study, list(finished.select_related("system")))[1])

    def practice(self, study: Study, rendered: list[Stimulus], planned: list[PlannedPage],
                 rng: random.Random) -> list[int]:
        wanted = self.practice_page_count(study)
        rated, checks = self._pairs(study, rendered)
        pages = rng.sample(checks, min(len(checks), wanted, 1))  # what an obvious mismatch looks like
        on_rated = {page.key for page in planned}
        others = [pair for pair in rated if key_of(list(pair)) not in on_rated]
        rng.shuffle(others)
        pages += others[:wanted - len(pages)]
        rng.shuffle(pages)
        return [s.id for pair in pages for s in rng.sample(pair, 2)]

    def task(self, study: Study) -> str:
        return ("Each page shows two clips, A and B, of a character asked to move in a certain way: say which "
                "clip's motion fits what it was asked better.")

    def page_context(self, study: Study, page: Page) -> dict:
        clips = page.clips
        shown = next((c.shown_control_id for c in clips if c.shown_control_id), clips[0].control_id if clips else None)
        control = ControlSignal.objects.filter(pk=shown).values_list("control", flat=True).first() or {}
        labels = {"action": control["action"], "style": control["style"]} if "action" in control else None
        return {**super().page_context(study, page), "labels": labels}

    def exclusion_reason(self, rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
        if not any(clip.assignment.is_check for clip in page):
            return ""
        mismatched = [clip for clip in page if clip.assignment.stimulus.shown_control_id is not None]
        failed = any(rules.preferred_attention(ATTENTION_NAME, answer.choice, SIDES.get(clip.assignment.slot))
                     for clip in mismatched)
        return rules.mismatch_reason if failed else ""

    def export_fields(self, assignment: Assignment, rating: Rating) -> dict:
        stimulus = assignment.stimulus
        shown = stimulus.shown_control or stimulus.control
        fields = {**super().export_fields(assignment, rating), "matched": stimulus.shown_control_id is None,
                  "shown_control": shown.name, "made_for": stimulus.control.name,
                  "control_class": shown.origin}  # a page's two rows are one page of its control
        if assignment.is_check:
            fields["system"] = ATTENTION_NAME
        return fields

    def monitor_tables(self, compared: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
        return [("Share of pages preferring the matched clip (no preference split; Wilson 95 % CI, sign test "
                 "against 50 %, Holm)", matched_preference(compared)),
                ("Mean appropriateness score, -2..+2 (95 % bootstrap CI over participants)",
                 appropriateness_scores(compared))]
