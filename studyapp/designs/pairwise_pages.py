"""The pairwise design: two systems' clips of one control on a page, and which is better
(left, right or no preference, with a strength where the study asks for one).

A participant answers ``pages_per_participant`` pages: ``bad_checks`` BAD-versus-NAT pages
(attention checks, no target) and the rest from every pair of non-BAD systems on every
control, among the least loaded the pair whose systems this participant has seen least.
Sides are balanced: each pair is shown in the order (left, right) it has been shown less
often. Preferring BAD on a page that shows it excludes the participant; "no preference"
there does not. An instructed check asks for clip A or B. Practice shows pairs too, about
``training_clips`` clips, a BAD-versus-NAT pair among them, none that the participant rates.

Adaptive pairing (the study's ``adaptive_pairing``): the pairs of systems on a new
participant's rated pages are planned at enrolment by `analysis.rankings.pairing.plan_pairs` from
the fit of the study's votes stored so far (kept participants' answered pages, early
answers left out where the study discards them), each page in turn where one more vote is
expected to narrow the leaderboard's intervals and settle its order most, a tenth of them
uniformly at random, and the pages that participants who have not finished hold
unanswered counted as shown; the sides balanced per pair of systems over the study. Each
page of a pair of systems shows it on another of its controls, the least loaded first,
never past ``ratings_per_stimulus`` (two pairs of systems may share a control on one
participant's pages). With fewer stored votes than pairs of systems the fit would be the
prior's, so pages are planned evenly as without the setting.

A round of a leaderboard (`studyapp.leaderboards`): the votes of the board's other rounds
in its fit count as votes so far too (among this study's systems, a system the same as a
board's where their names in the ratings table are equal), so a new system's first round is
planned against the board's current estimates: its pages go where the board is least certain
of it, from the first participant on. Those votes are only read; their sides, balanced per
pair within their own study, count with the rest.

ABX, the variant: the control's natural clip is shown above A and B as a reference X, and
the question is which of them is closer to it; pages pair the systems other than NAT, on
controls with a natural clip (held-out controls), and X is not a row of the ratings table.
"""

from __future__ import annotations

import itertools
import math
import random
from collections import Counter

import numpy as np
import pandas as pd
from django.http import QueryDict

from analysis.ratings.exclusions import ExclusionRules
from analysis.rankings.pairing import plan_pairs
from analysis.stats.preferences import preference_pairs
from studyapp.designs.answers import whole_number
from studyapp.designs.design import Answer, OnPage, Page, PlannedPage, clip_label
from studyapp.designs.multi_clip import MultiClip, bad_for, by_control, key_of, page_orders
from studyapp.designs.reasons import check_reasons, read_reasons, reasons_context
from studyapp.models import Assignment, Rating, Stimulus, Study, System, export_name
from studyapp.participants.refusal import AnswerRefused

SIDES = {Assignment.LEFT: Rating.Answer.LEFT, Assignment.RIGHT: Rating.Answer.RIGHT}  # slot -> side


def balanced_sides(pair: tuple[Stimulus, Stimulus], orders: Counter, rng: random.Random) -> list[Stimulus]:
    """The pair in the order (left, right) it has been shown less often (ties at random); ``orders`` is updated."""
    key = frozenset(s.id for s in pair)
    both = [list(pair), list(pair[::-1])]
    rng.shuffle(both)
    order = min(both, key=lambda clips: orders[key, tuple(s.id for s in clips)])
    orders[key, tuple(s.id for s in order)] += 1
    return order


def stored_pages(study: Study) -> pd.DataFrame:
    """The study's rated (not check) pages so far, one row each: system_left, system_right,
    answer and strength (empty until answered), ``vote`` (answered by a kept participant,
    and not early where the study discards early answers) and ``held`` (unanswered, its
    participant not finished)."""
    rows = (Assignment.objects.filter(participant__study=study, is_check=False, expected="")
            .values_list("participant_id", "page", "slot", "stimulus__system__name", "rating__answer",
                         "rating__strength", "rating__answered_before_end", "participant__excluded",
                         "participant__finished_at"))
    pages: dict[tuple[int, int], dict] = {}
    for participant, page, slot, system, answer, strength, early, excluded, finished in rows:
        row = pages.setdefault((participant, page), {"answer": answer, "strength": strength, "early": False,
                                                     "excluded": excluded, "finished": finished is not None})
        row["system_left" if slot == Assignment.LEFT else "system_right"] = system
        row["early"] |= bool(early)
    table = pd.DataFrame(list(pages.values()), columns=["system_left", "system_right", "answer", "strength", "early",
                                                        "excluded", "finished"])
    answered = table["answer"].notna()
    table["vote"] = answered & ~table["excluded"].astype(bool) & ~(study.discard_early & table["early"].astype(bool))
    table["held"] = ~answered & ~table["finished"].astype(bool)
    return table.drop(columns=["early", "excluded", "finished"])


def board_votes(study: Study) -> pd.DataFrame:
    """The votes (rows of `stored_pages`, renamed to this study's system names) of the other
    rounds in the fit of the leaderboard the study is a round of; empty if it is none's."""
    columns = ["system_left", "system_right", "answer", "strength"]
    board_round = getattr(study, "board_round", None)
    if board_round is None:
        return pd.DataFrame(columns=columns)
    ours = {export_name(role, name): name for name, role in study.systems.values_list("name", "role")}
    frames = []
    for other in board_round.leaderboard.rounds.filter(in_fit=True).exclude(pk=board_round.pk).select_related("study"):
        theirs = {name: ours.get(export_name(role, name)) for name, role in other.study.systems.values_list("name", "role")}
        pages = stored_pages(other.study)
        pages = pages[pages["vote"]].assign(system_left=lambda t: t["system_left"].map(theirs),
                                            system_right=lambda t: t["system_right"].map(theirs))
        frames.append(pages.dropna(subset=["system_left", "system_right"])[columns])
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)


def strength_words(count: int) -> list[tuple[int, str]]:
    """Each strength of a preference, 1 to ``count``, with the word its button shows: the
    weakest "slightly", the strongest "clearly" (GENEA's words, as the docs and the
    appropriateness pages say them), any between by its number."""
    words = {1: "slightly", count: "clearly"} if count > 1 else {1: "clearly"}
    return [(point, words.get(point, str(point))) for point in range(1, count + 1)]


class Pairwise(MultiClip):
    template = "pairwise.html"
    settings = ("pages_per_participant", "abx", "preference_strengths", "adaptive_pairing", "reasons",
                "reasons_required")
    export_columns = ("design", "page", "side", "answer", "strength")
    on_scale = False

    def check_pages(self, study: Study) -> int:
        return study.bad_checks

    def clips_per_page(self, study: Study) -> float:
        return 2.0 + study.abx  # and the reference X

    def practice_page_count(self, study: Study) -> int:
        return math.ceil(study.training_clips / 2)  # pairs

    def _pairable(self, study: Study, rendered: list[Stimulus]) -> tuple[dict, dict, list[Stimulus]]:
        """Clips per control that pages pair, BAD clips per control, and the natural clips."""
        clips, bad = by_control(rendered)
        natural = [s for page in clips.values() for s in page if s.system.role == System.Role.NATURAL]
        if study.abx:  # X is the control's natural clip: held-out controls only, and NAT is not paired with itself
            with_x = {s.control_id for s in natural}
            clips = {control: [s for s in page if s.system.role != System.Role.NATURAL]
                     for control, page in clips.items() if control in with_x}
        return clips, bad, natural

    def _checks(self, natural: list[Stimulus], bad: dict, count: int, orders: Counter,
                rng: random.Random) -> list[PlannedPage]:
        """Up to ``count`` BAD-versus-NAT pages."""
        natural = list(natural)
        rng.shuffle(natural)
        checks = []
        for nat in natural[:count]:
            anchor = bad_for(nat.control_id, bad, rng)
            if anchor is not None:
                checks.append(PlannedPage(balanced_sides((nat, anchor), orders, rng), is_check=True))
        return checks

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        clips, bad, natural = self._pairable(study, rendered)
        orders = page_orders(study)
        checks = self._checks(natural, bad, study.bad_checks, orders, rng)
        pairs = [pair for page in clips.values() for pair in itertools.combinations(page, 2)
                 if loads[key_of(list(pair))] < study.ratings_per_stimulus]
        rng.shuffle(pairs)  # ties at random: min() takes the first
        wanted = count - len(checks)
        adaptive = self._adaptive_pages(study, pairs, loads, wanted, rng) if study.adaptive_pairing else None
        rated = adaptive if adaptive is not None else self._even_pages(pairs, loads, wanted, orders, rng)
        if not rated:
            return []
        for check in checks:
            rated.insert(rng.randint(0, len(rated)), check)
        return rated

    def _even_pages(self, pairs: list[tuple[Stimulus, Stimulus]], loads: Counter, wanted: int, orders: Counter,
                    rng: random.Random) -> list[PlannedPage]:
        """Up to ``wanted`` pages, the least loaded pair first and among those the pair whose
        systems this participant has seen least; sides balanced per pair of clips."""
        pairs = list(pairs)
        seen: Counter = Counter()  # systems on this participant's rated pages (the checks are not analysed)
        rated = []
        while pairs and len(rated) < wanted:
            pair = min(pairs, key=lambda p: (loads[key_of(list(p))], seen[p[0].system_id] + seen[p[1].system_id]))
            pairs.remove(pair)
            seen.update(s.system_id for s in pair)
            rated.append(PlannedPage(balanced_sides(pair, orders, rng)))
        return rated

    def _adaptive_pages(self, study: Study, pairs: list[tuple[Stimulus, Stimulus]], loads: Counter, wanted: int,
                        rng: random.Random) -> list[PlannedPage] | None:
        """Up to ``wanted`` pages whose pairs of systems `analysis.rankings.pairing.plan_pairs` plans
        from the votes so far (see the module's docstring); None with too few votes."""
        by_systems: dict[frozenset[str], list[tuple[Stimulus, Stimulus]]] = {}
        for pair in sorted(pairs, key=lambda p: loads[key_of(list(p))]):  # stable: random among equal loads
            by_systems.setdefault(frozenset(s.system.name for s in pair), []).append(pair)
        systems = sorted({s.system.name for pair in pairs for s in pair})
        stored = stored_pages(study)
        among = stored["system_left"].isin(systems) & stored["system_right"].isin(systems)
        board = board_votes(study)
        board = board[board["system_left"].isin(systems) & board["system_right"].isin(systems)]
        votes, held = pd.concat([board, stored[among & stored["vote"]]], ignore_index=True), stored[among & stored["held"]]
        if len(systems) < 2 or len(votes) < len(systems) * (len(systems) - 1) // 2:
            return None
        natural = {s.system.name for pair in pairs for s in pair if s.system.role == System.Role.NATURAL}
        planned = plan_pairs(votes, systems, wanted, np.random.default_rng(rng.getrandbits(64)),
                             anchor=next(iter(natural), None), held=held,
                             capacity={key: len(clips) for key, clips in by_systems.items()})
        rated = []
        for left, right in planned:
            pair = by_systems[frozenset((left, right))].pop(0)  # the least loaded control of the pair
            rated.append(PlannedPage(sorted(pair, key=lambda s: s.system.name != left)))
        return rated

    def practice(self, study: Study, rendered: list[Stimulus], planned: list[PlannedPage],
                 rng: random.Random) -> list[int]:
        wanted = self.practice_page_count(study)
        clips, bad, natural = self._pairable(study, rendered)
        pages = self._checks(natural, bad, min(wanted, 1), Counter(), rng)  # what broken motion looks like
        rated = {page.key for page in planned}
        pairs = [pair for page in clips.values() for pair in itertools.combinations(page, 2)
                 if key_of(list(pair)) not in rated]
        rng.shuffle(pairs)
        pages += [PlannedPage(list(pair)) for pair in pairs[:wanted - len(pages)]]
        rng.shuffle(pages)
        return [s.id for page in pages for s in page.clips]

    def strengths(self, study: Study) -> range:
        """The strengths a preference is given with (empty: none asked)."""
        return study.strengths

    def practice_pages(self, clips: list[Stimulus]) -> list[list[Stimulus]]:
        return [clips[i:i + 2] for i in range(0, len(clips), 2)]

    def instructed_answer(self, study: Study, clips: list[Stimulus], rng: random.Random) -> list[str]:
        return [rng.choice((Rating.Answer.LEFT.value, Rating.Answer.RIGHT.value))] * len(clips)

    def instruction(self, study: Study, expected: list[str]) -> str:
        label = clip_label(Assignment.LEFT if expected[0] == Rating.Answer.LEFT else Assignment.RIGHT)
        return f"Attention check: whatever you think of these clips, please choose clip {label}."

    def follows_instruction(self, study: Study, expected: list[str], answer: Answer) -> bool:
        return answer.choice == expected[0]

    def task(self, study: Study) -> str:
        if study.abx:
            return "Each page shows a reference clip X and two clips, A and B: say which of them is closer to X."
        return f"Each page shows two clips, A and B. {study.question} Say which clip is better."

    def page_context(self, study: Study, page: Page) -> dict:
        return {**super().page_context(study, page), "strengths": strength_words(len(self.strengths(study))),
                "reference": self._reference(study, page), **reasons_context(study)}

    def _reference(self, study: Study, page: Page) -> dict | None:
        """ABX: the page's reference X, the natural clip of its control (played like the others, not rated)."""
        if not study.abx:
            return None
        natural = Stimulus.objects.filter(study=study, control_id=page.clips[0].control_id,
                                          status=Stimulus.Status.DONE, system__role=System.Role.NATURAL).first()
        return {"video_url": natural.video_url} if natural else None

    def read_answer(self, study: Study, form: QueryDict) -> Answer:
        reasons, other = read_reasons(study, form)
        return Answer(form.get(self.form_field, ""), self.slot_times(form, list(SIDES)),
                      choice=form.get("answer", "").strip(),
                      strength=whole_number(form, "strength", "the strength of the preference"),
                      reasons=reasons, other_reason=other)

    def check_answer(self, study: Study, answer: Answer, slots: list[int]) -> None:
        if answer.choice not in Rating.Answer.values:
            raise AnswerRefused(f"the answer must be one of {', '.join(Rating.Answer.values)}, "
                                f"not {answer.choice[:20]!r}")
        strengths = self.strengths(study)
        if answer.choice == Rating.Answer.NONE or not strengths:
            if answer.strength is not None:
                raise AnswerRefused("a strength goes with a preference for one clip, and only where the study asks it")
        elif answer.strength not in strengths:
            raise AnswerRefused(f"the strength of the preference must be a whole number from 1 to {len(strengths)}")
        check_reasons(study, answer.reasons, answer.other_reason)

    def exclusion_reason(self, rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
        preferred = any(rules.preferred_attention(clip.system, answer.choice, SIDES.get(clip.assignment.slot))
                        for clip in page)
        return rules.preference_reason if preferred else ""

    def export_fields(self, assignment: Assignment, rating: Rating) -> dict:
        return {"design": self.name, "page": assignment.page + 1,
                "side": SIDES.get(assignment.slot, Rating.Answer.RIGHT).value, "answer": rating.answer,
                "strength": rating.strength}

    def monitor_tables(self, compared: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
        return [("Preference per pair (Wilson 95 % CI, sign test, Holm)", preference_pairs(compared))]
