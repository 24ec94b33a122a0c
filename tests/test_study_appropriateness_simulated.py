"""Simulated participants who prefer the matched clip with a known probability per system
take a live appropriateness study over HTTP; its report recovers each probability within
its interval."""

from __future__ import annotations

import io
import random
import re

import pytest

from analysis.stats.matching import matched_preference
from analysis.ratings.exclusions import apply_exclusions, compared_ratings
from analysis.ratings.schema import read_ratings
from studyapp.designs.rules import StudyRules
from studyapp.models import Assignment
from studyapp.participants import assignment
from studyapp.participants.simulated import SimulatedParticipant
from studyapp.researchers.results.export import ratings_csv
from tests.appropriateness_fixtures import make_appropriateness_study

PREFER_MATCHED = {"MoGlow": 0.8, "RNN": 0.55, "NAT": 0.95}
PAGE_TOKEN = re.compile(r'<input type="hidden" name="page" value="([0-9a-f]+)">')


class Discerning(SimulatedParticipant):
    """Prefers the matched clip of a system's page with that system's probability, slightly
    or clearly at random; on an attention check always the matched one."""

    def _page_answer(self, body: str, sliders, answers, strengths) -> dict:
        data = super()._page_answer(body, sliders, answers, strengths)
        token = PAGE_TOKEN.search(body)
        if token is None:  # a practice page: any answer
            return data
        first = Assignment.objects.select_related("stimulus__system").get(token=token.group(1))
        page = Assignment.objects.filter(participant=first.participant_id, page=first.page).select_related("stimulus")
        matched = next(a for a in page if a.stimulus.shown_control_id is None)
        likes_matched = first.is_check or self.rng.random() < PREFER_MATCHED[first.stimulus.system.name]
        prefers_left = (matched.slot == Assignment.LEFT) == likes_matched
        return {**data, "answer": "left" if prefers_left else "right", "strength": self.rng.choice(strengths)}


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_simulated_preferences_for_the_matched_clip_are_recovered_within_their_intervals(live_server, monkeypatch):
    # Enrolment draws its plans from the system's randomness; seeded here, so that the
    # answers, and whether each 95 % interval covers its probability, are the same every run.
    plans = random.Random(3)
    monkeypatch.setattr(assignment.random, "SystemRandom", lambda: random.Random(plans.random()))
    study = make_appropriateness_study(clip_seconds=0.05, pages_per_participant=12, ratings_per_stimulus=100,
                                       training_clips=2)
    for n in range(24):
        outcome = Discerning(f"{live_server.url}/p/{study.key}/", f"sim-{n:02d}").run()
        assert outcome.finished, outcome.error or outcome.final_page[-300:]

    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    rules = StudyRules.of(study).exclusion
    flagged = apply_exclusions(table, rules)
    assert not flagged["excluded_participant"].any()  # every check passed
    compared = compared_ratings(flagged, rules)
    shares = matched_preference(compared, groupby=()).set_index("system")
    assert set(shares.index) == set(PREFER_MATCHED)
    for system, probability in PREFER_MATCHED.items():
        row = shares.loc[system]
        assert row["n_pages"] >= 60 and row["no_preference"] == 0
        assert row["ci_low"] <= probability <= row["ci_high"], (system, row.to_dict())
    assert shares.loc["NAT", "ci_low"] > 0.5 + 1e-9 and shares.loc["RNN", "ci_low"] < 0.5  # told apart from chance
