"""How many participants a study plans for: its targets' number, or the power of its test.

The targets' number is what enrolment would admit: the study's design plans one
participant's pages after another (``Design.plan``, seeded, as enrolment does with each
page's load) over the study's clips, every participant answering every page, until
every page has its target number of answers (``ratings_per_stimulus``); the study then
turns new participants away.

With an expected effect (``Study.expected_effect``), the number is the power module's:
the analysis' object of the study's design gives the units (ratings per system, pages
per pair) its test needs to detect that effect at the report's alpha, split over the
pairs of compared systems, with the report's power (``analysis.stats.power``); the same
simulated pages say how many of those units one participant gives to the least served
system or pair, and so how many participants give them all.
"""

from __future__ import annotations

import math
import random
from collections import Counter
from itertools import combinations

from analysis.levels import ALPHA, POWER
from analysis.designs import design_named as analysed_design
from studyapp.designs.design import PlannedPage
from studyapp.designs.registry import design_of
from studyapp.models import Stimulus, Study, System

# Past this many simulated participants the targets' number is not worth the time it takes.
MOST_SIMULATED = 20_000


def simulated_pages(study: Study) -> list[list[PlannedPage]]:
    """Every participant's pages, in order of arrival, until the targets are met (at most ``MOST_SIMULATED``)."""
    design = design_of(study)
    clips = list(study.stimuli.exclude(status=Stimulus.Status.FAILED).select_related("system"))
    rng = random.Random(study.key)
    loads: Counter = Counter()
    participants = []
    while len(participants) < MOST_SIMULATED:
        pages = design.plan(study, clips, loads, design.page_count(study) - study.instructed_checks, rng)
        if not pages:
            break
        loads.update(page.key for page in pages)
        participants.append(pages)
    return participants


def compared_units(participants: list[list[PlannedPage]], per_pair: bool) -> tuple[int, float]:
    """How many systems the pages compare (every one shown but BAD: an ABX page's
    reference is no clip of the page), and what the least served of them (or of their
    pairs) gets from one participant on average: its clips, or the pages showing both."""
    counts: Counter = Counter()
    systems = set()
    for pages in participants:
        for page in pages:
            shown = sorted({clip.system_id for clip in page.clips if clip.system.role != System.Role.BAD})
            systems.update(shown)
            counts.update(combinations(shown, 2) if per_pair else shown)
    wanted = list(combinations(sorted(systems), 2)) if per_pair else sorted(systems)
    return len(systems), min((counts[unit] for unit in wanted), default=0) / max(len(participants), 1)


def planned_participants(study: Study) -> dict:
    """The plan's number of participants and how it was reached (plain data):
    ``planned`` (None where no number can be given, ``why`` then says so), ``source``
    ("targets" or "power"), ``targets_admit`` and, from the power, the effect, the units
    needed and the units a participant gives."""
    participants = simulated_pages(study)
    admitted = len(participants)
    section = {"targets_admit": admitted if admitted < MOST_SIMULATED else None, "alpha": ALPHA, "power": POWER,
               "expected_effect": study.expected_effect}
    if study.expected_effect is None:
        why = ("the study had no clips when it opened" if not admitted else
               f"its targets admit more than {MOST_SIMULATED:,} participants" if admitted >= MOST_SIMULATED else "")
        return {**section, "source": "targets", "planned": None if why else admitted, "why": why}
    analysed = analysed_design(study.design)
    compared, rate = compared_units(participants, analysed.units_per_pair)
    section.update(source="power", effect_words=analysed.effect_words, unit=analysed.planned_unit,
                   per_pair=analysed.units_per_pair, compared_systems=compared)
    if compared < 2:
        return {**section, "planned": None, "why": "its pages compare fewer than two systems"}
    try:
        units = analysed.planned_units(study.expected_effect, compared, ALPHA, POWER)
    except ValueError as error:  # an effect saved past the form's check (Study.clean)
        return {**section, "planned": None, "why": str(error)}
    if not rate:
        return {**section, "planned": None, "units": units,
                "why": "its pages never show some pair of the compared systems together"}
    return {**section, "planned": math.ceil(units / rate), "units": units, "units_per_participant": round(rate, 6),
            "why": ""}
