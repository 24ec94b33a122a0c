"""Rating designs in the analysis are objects: what differs between designs is asked of the
table's design object (`analysis.designs`), no analysis code outside the designs package
compares a design's name, and each design states its rules in one wording, its report's."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis import build_report, validate_ratings
from analysis.cli import main
from analysis.designs import DESIGNS, design_named, design_of
from analysis.ratings.exclusions import ExclusionRules
from analysis.reports.single_report import summary_text
from analysis.ratings.simulate import (simulate_appropriateness, simulate_pairwise, simulate_ratings,
                               simulate_side_by_side)

ANALYSIS = Path(__file__).resolve().parents[1] / "analysis"
NAMES = "|".join(re.escape(name) for name in DESIGNS)
# A design's constant, a comparison with (or a dict keyed by) a design's name, or reading the
# name of a table's design where its object would answer.
NAMES_A_DESIGN = re.compile(
    r"\b(SINGLE|SIDE_BY_SIDE|PAIRWISE|APPROPRIATENESS|PREFERENCE_DESIGNS)\b"
    rf"|(==|!=|\bin)\s*[(\[{{]?\s*['\"]({NAMES})['\"]"
    rf"|['\"]({NAMES})['\"]\s*(==|!=|\bin\b|\bnot in\b|:)"
    r"|\btable_design\(|\bdesign\.name\s*(==|!=|\bin\b|\bnot in\b)")

TABLES = {
    "single": lambda: simulate_ratings({"NAT": 4.2, "A": 3.4}, 400, seed=1),
    "side-by-side": lambda: simulate_side_by_side({"NAT": 75, "A": 55, "BAD": 10}, 12, seed=1),
    "pairwise": lambda: simulate_pairwise({"NAT": 1.0, "A": 0.0, "BAD": -5.0}, 16, seed=1),
    "appropriateness": lambda: simulate_appropriateness({"NAT": 0.9, "A": 0.6}, 16, seed=1),
}
# Each design's attention rule as the app states it, and as the report's summary says it.
RULES_IN_WORDS = {
    "single": ("A participant was removed who rated any BAD clip 4 or higher or any NAT clip below 2 "
               "(on a 1-5 scale; scaled linearly on others).",
               "a participant was removed who rated any BAD clip 4 or higher or any NAT clip below 2 "
               "(on a 1-5 scale; scaled linearly on others)"),
    "side-by-side": ("A participant was removed who rated any BAD clip 4 or higher or any NAT clip below 2 "
                     "(on a 1-5 scale; scaled linearly on others).",
                     "a participant was removed who rated any BAD clip 75 or higher or any NAT clip below 25 "
                     "(on the 0-100 scale)"),
    "pairwise": ("A participant was removed who preferred a BAD clip on any page showing one.",
                 "a participant was removed who preferred a BAD clip on any page showing one"),
    "appropriateness": ("A participant was removed who preferred the mismatched clip of any BAD page.",
                        "a participant was removed who preferred the mismatched clip of any BAD page"),
}


def test_no_code_outside_the_designs_compares_a_designs_name():
    found = [f"{path.relative_to(ANALYSIS)}:{number}: {line.strip()}"
             for path in sorted(ANALYSIS.rglob("*.py")) if not path.is_relative_to(ANALYSIS / "designs")
             for number, line in enumerate(path.read_text().splitlines(), start=1) if NAMES_A_DESIGN.search(line)]
    assert found == []


def test_the_pattern_finds_the_comparisons_it_forbids():
    for line in ('if table_design(ratings) != APPROPRIATENESS:', 'if design in PREFERENCE_DESIGNS:',
                 'per_pair = {SIDE_BY_SIDE: _side_by_side_pairs}', 'if kind == "pairwise":',
                 'if design.name in ("single", "side-by-side"):', 'if "appropriateness" == name:'):
        assert NAMES_A_DESIGN.search(line), line
    for line in ('table.insert(0, "design", "pairwise")', 'if design not in DESIGNS:  # uniform or adaptive',
                 'design = design_of(ratings)', 'f"{args.ratings} is {design.name}"'):
        assert not NAMES_A_DESIGN.search(line), line


@pytest.mark.parametrize("name", TABLES)
def test_each_table_is_analysed_by_its_designs_object(name):
    ratings = validate_ratings(TABLES[name]())
    assert design_of(ratings) is design_named(name) and design_named(name).name == name


@pytest.mark.parametrize("name", TABLES)
def test_each_design_states_its_rules_in_the_words_of_its_report(name):
    design, (stated, in_report) = design_named(name), RULES_IN_WORDS[name]
    assert design.described(ExclusionRules())[0] == stated
    assert in_report in summary_text(build_report(validate_ratings(TABLES[name]())))


def test_the_rated_designs_state_the_early_rule_per_rating_and_the_preference_designs_per_page():
    keep, discard = ExclusionRules(discard_early=False), ExclusionRules()
    for name in ("single", "side-by-side"):
        assert design_named(name).described(discard)[-1] == (
            "A rating given before its clip had finished playing is discarded.")
        assert design_named(name).described(keep)[-1] == "Ratings given before their clip had finished playing are kept."
    for name in ("pairwise", "appropriateness"):
        assert design_named(name).described(discard)[-1] == (
            "A page answered before its clips had finished playing is discarded whole.")
        assert design_named(name).described(keep)[-1] == "Pages answered before their clips had finished playing are kept."


def test_a_preference_design_says_that_the_rating_thresholds_do_not_apply_to_it():
    rules = ExclusionRules(bad_at_or_above=3.5, natural_below=4.5)
    assert design_named("pairwise").described(rules)[1] == (
        "The rating thresholds (BAD 3.5 or higher, NAT below 4.5, on a 1-5 scale) do not apply: pairwise pages "
        "are answered by a preference, not rated.")
    assert all("threshold" not in sentence for sentence in design_named("single").described(rules))


def test_comparing_the_attention_system_is_stated_alike_in_every_design():
    compared = ExclusionRules(attention_rule=False)
    assert design_named("single").described(compared)[0] == (
        "A participant was removed who rated any NAT clip below 2 (on a 1-5 scale; scaled linearly on others); "
        "BAD was compared as a system, not used as an attention check.")
    for name in ("pairwise", "appropriateness"):
        assert design_named(name).described(compared)[0] == (
            "No attention check was applied (BAD was compared as a system).")


@pytest.fixture
def thumbs(monkeypatch):
    """The toy design's analysis registered (tests/toy_analysis_design.py)."""
    monkeypatch.setitem(DESIGNS, "thumbs", "tests.toy_analysis_design:Thumbs")
    yield
    design_named.cache_clear()


def thumbs_table() -> pd.DataFrame:
    """12 participants giving thumbs up or down; p0 gives BAD a thumbs up, p1 NAT a thumbs down."""
    rng = np.random.default_rng(3)
    rows = [{"participant": f"p{p}", "system": system, "stimulus": f"{system}{clip}",
             "value": int(p == 0) if system == "BAD" else int(p != 1) if system == "NAT" and clip == 0
             else int(rng.random() < share)}
            for p in range(12) for system, share in (("NAT", 1.0), ("A", 0.7), ("B", 0.3), ("BAD", 0.0))
            for clip in range(5 if system != "BAD" else 1)]
    return pd.DataFrame(rows).assign(design="thumbs", scale_min=0, scale_max=1)


def test_a_new_designs_analysis_is_one_module_and_one_registration(thumbs, tmp_path):
    table = thumbs_table()
    table.to_csv(tmp_path / "ratings.csv", index=False)
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(tmp_path / "out")]) == 0

    kept = table[~table["participant"].isin(["p0", "p1"]) & (table["system"] != "BAD")]
    shares = pd.read_csv(tmp_path / "out" / "tables" / "thumbs_up.csv").set_index("system")["share_up"]
    assert shares.to_dict() == pytest.approx(kept.groupby("system")["value"].mean().to_dict())
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert ("Of 12 participants, 2 were removed for failing attention checks (1 rated a BAD clip high, 1 rated a "
            "NAT clip low); a participant was removed who rated any BAD clip 0.75 or higher or any NAT clip below "
            "0.25 (on the 0-1 scale).") in summary
    assert f"thumbs up: A {shares['A'] * 100:.0f} % of 50" in summary
