"""Which pages a new participant answers in the side-by-side and pairwise designs.

A page is identified by its content: the ids of its non-BAD clips (a side-by-side page
is one control's clips of every system; a pairwise page one control's clips of two
systems). Its load counts the participants who answered it and are kept (not excluded,
no clip of it answered before its end where early answers are discarded) plus those who
hold it while still active, as ``assignment.stimulus_loads`` counts single clips; pages
are handed out least loaded first and never past ``ratings_per_stimulus``.

- Side-by-side: ``pages_per_participant`` controls' pages; every system with a clip of
  the control is on its page (NAT as a hidden reference), and a BAD clip joins
  ``bad_checks`` of them as an anchor. The order on a page is the next row of a
  Williams design (``williams_row``), so positions and neighbours are counterbalanced.
- Pairwise: ``bad_checks`` BAD-versus-NAT pages (attention checks, no target) and the
  rest from every pair of non-BAD systems on every control (ABX: of the systems other
  than NAT, on controls with a natural clip to show as X), among the least loaded the
  pair whose systems this participant has seen least. Sides are balanced: each pair is
  shown in the order (left, right) it has been shown less often.

Callers hold the study's lock (``assignment.enrol``), so loads cannot move underneath.
"""

from __future__ import annotations

import itertools
import random
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from datetime import datetime

from studyapp.models import Assignment, Stimulus, Study, System

PageKey = frozenset[int]  # the ids of a page's non-BAD clips


@dataclass
class PlannedPage:
    """One page of a participant's plan: its clips in slot order."""

    clips: list[Stimulus]
    is_check: bool = False
    expected: list[str] = field(default_factory=list)  # an instructed check's answer, per clip

    @property
    def key(self) -> PageKey:
        return frozenset(s.id for s in self.clips if s.system.role != System.Role.BAD)


def page_loads(study: Study, cutoff: datetime) -> Counter:
    """Load of each page content (``PageKey``): kept answered pages plus pages held by
    participants active since ``cutoff``. Instructed checks repeat other pages and do not count."""
    rows = (Assignment.objects.filter(participant__study=study, participant__excluded=False, expected="")
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


def _by_control(rendered: list[Stimulus]) -> tuple[dict[int, list[Stimulus]], dict[int | None, list[Stimulus]]]:
    """Non-BAD clips per control (one per system: the first rendered) and BAD clips per
    control (None: uploaded BAD videos, which can join any page)."""
    clips: dict[int, dict[int, Stimulus]] = defaultdict(dict)
    bad: dict[int | None, list[Stimulus]] = defaultdict(list)
    for stimulus in sorted(rendered, key=lambda s: s.id):
        if stimulus.system.role == System.Role.BAD:
            bad[stimulus.control_id].append(stimulus)
        elif stimulus.control_id is not None:
            clips[stimulus.control_id].setdefault(stimulus.system_id, stimulus)
    return {control: list(systems.values()) for control, systems in clips.items()}, bad


def _bad_for(control: int, bad: dict[int | None, list[Stimulus]], rng: random.Random) -> Stimulus | None:
    """A BAD clip for a page of ``control``: its own if it has one, else an uploaded one."""
    candidates = bad.get(control) or bad.get(None) or []
    return rng.choice(candidates) if candidates else None


def _balanced_sides(pair: tuple[Stimulus, Stimulus], orders: Counter, rng: random.Random) -> list[Stimulus]:
    """The pair in the order (left, right) it has been shown less often (ties at random); ``orders`` is updated."""
    key = frozenset(s.id for s in pair)
    both = [list(pair), list(pair[::-1])]
    rng.shuffle(both)
    order = min(both, key=lambda clips: orders[key, tuple(s.id for s in clips)])
    orders[key, tuple(s.id for s in order)] += 1
    return order


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
    orders[PlannedPage(order).key, tuple(s.id for s in order)] += 1
    return order


def side_by_side_plan(study: Study, rendered: list[Stimulus], loads: Counter, orders: Counter,
                      rng: random.Random) -> list[PlannedPage]:
    clips, bad = _by_control(rendered)
    pages = [page for page in clips.values() if len(page) >= 2]
    rng.shuffle(pages)  # ties at random: sort() is stable
    pages.sort(key=lambda page: loads[frozenset(s.id for s in page)])
    chosen = [page for page in pages if loads[frozenset(s.id for s in page)] < study.ratings_per_stimulus]
    chosen = chosen[:study.pages_per_participant]
    planned = []
    for index, page in enumerate(chosen):
        anchor = _bad_for(page[0].control_id, bad, rng) if index < study.bad_checks else None
        # Each control's design starts at a row of its own, fixed for the study, so that
        # the first participants do not all see the same order on every page.
        offset = random.Random(f"{study.key}:{page[0].control_id}").randrange(2 * len(page) + 2)
        planned.append(PlannedPage(_williams_order(page + ([anchor] if anchor else []), orders, offset),
                                   is_check=anchor is not None))
    rng.shuffle(planned)
    return planned


def pairwise_plan(study: Study, rendered: list[Stimulus], loads: Counter, orders: Counter,
                  rng: random.Random) -> list[PlannedPage]:
    clips, bad = _by_control(rendered)
    checks = []
    natural = [s for page in clips.values() for s in page if s.system.role == System.Role.NATURAL]
    if study.abx:  # X is the control's natural clip: held-out controls only, and NAT is not paired with itself
        with_x = {s.control_id for s in natural}
        clips = {control: [s for s in page if s.system.role != System.Role.NATURAL]
                 for control, page in clips.items() if control in with_x}
    rng.shuffle(natural)
    for nat in natural[:study.bad_checks]:
        anchor = _bad_for(nat.control_id, bad, rng)
        if anchor is not None:
            checks.append(PlannedPage(_balanced_sides((nat, anchor), orders, rng), is_check=True))
    pairs = [pair for page in clips.values() for pair in itertools.combinations(page, 2)
             if loads[frozenset(s.id for s in pair)] < study.ratings_per_stimulus]
    rng.shuffle(pairs)  # ties at random: min() takes the first
    seen: Counter = Counter()  # systems on this participant's rated pages (the checks are not analysed)
    rated = []
    while pairs and len(rated) + len(checks) < study.pages_per_participant:
        pair = min(pairs, key=lambda p: (loads[frozenset(s.id for s in p)], seen[p[0].system_id] + seen[p[1].system_id]))
        pairs.remove(pair)
        seen.update(s.system_id for s in pair)
        rated.append(PlannedPage(_balanced_sides(pair, orders, rng)))
    if not rated:
        return []
    for check in checks:
        rated.insert(rng.randint(0, len(rated)), check)
    return rated
