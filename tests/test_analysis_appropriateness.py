"""Appropriateness statistics against independent computations, and simulated participants.

References: scipy.stats.binomtest (sign test), statsmodels' proportion_confint (Wilson,
with "no preference" split half and half) and multipletests (Holm), scipy.stats.wilcoxon
(pairs of systems), and a bootstrap over participants written here with a loop.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from statsmodels.stats.multitest import multipletests
from statsmodels.stats.proportion import proportion_confint

from analysis.stats.matching import (appropriateness_pages, appropriateness_scores, matched_preference,
                                      score_pairs)
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import apply_exclusions
from analysis.ratings.schema import validate_ratings
from analysis.ratings.simulate import simulate_appropriateness

PREFER_MATCHED = {"NAT": 0.92, "MoGlow": 0.78, "RNN": 0.62, "Chance": 0.5}
NO_PREFERENCE, CLEAR = 0.15, 0.5


@pytest.fixture(scope="module")
def simulated() -> pd.DataFrame:
    table = simulate_appropriateness(PREFER_MATCHED, n_participants=120, no_preference_share=NO_PREFERENCE,
                                     clear_share=CLEAR, inattentive_share=0.0, early_share=0.0, seed=7)
    flagged = apply_exclusions(validate_ratings(table.astype(str)))
    return flagged[flagged["kept"] & (flagged["system"] != "BAD")]


def page(participant: str, name: str, system: str, matched_side: str, answer: str, strength="") -> list[dict]:
    """The two rows of one appropriateness page."""
    return [{"design": "appropriateness", "participant": participant, "page": name, "system": system,
             "stimulus": f"{system}_{name}_{side}", "side": side, "matched": side == matched_side,
             "answer": answer, "strength": "" if answer == "none" else strength}
            for side in ("left", "right")]


def test_scores_are_plus_for_the_matched_clip_minus_for_the_other_and_zero_for_none():
    rows = (page("p1", "q1", "A", "left", "left", 2) + page("p1", "q2", "A", "right", "left", 1)
            + page("p1", "q3", "A", "left", "none") + page("p2", "q1", "A", "right", "right", 1)
            + page("p2", "q2", "A", "left", "right", 2))
    pages = appropriateness_pages(validate_ratings(pd.DataFrame(rows).astype(str)))
    assert pages["score"].tolist() == [2, -1, 0, 1, -2]
    assert pages["preferred"].tolist() == ["matched", "mismatched", "none", "matched", "mismatched"]
    without_strength = validate_ratings(pd.DataFrame(rows).drop(columns="strength").astype(str))
    assert appropriateness_pages(without_strength)["score"].tolist() == [1, -1, 0, 1, -1]


def test_share_preferring_matched_splits_ties_and_equals_statsmodels_and_scipy(simulated):
    table = matched_preference(simulated)
    pages = appropriateness_pages(simulated)
    for row in table.itertuples():
        mine = pages[pages["system"] == row.system]
        matched, mismatched = (mine["preferred"] == "matched").sum(), (mine["preferred"] == "mismatched").sum()
        ties = (mine["preferred"] == "none").sum()
        assert (row.matched, row.mismatched, row.no_preference, row.n_pages) == (matched, mismatched, ties, len(mine))
        assert row.share_matched == pytest.approx((matched + ties / 2) / len(mine), abs=1e-12)
        assert (row.ci_low, row.ci_high) == pytest.approx(
            proportion_confint(matched + ties / 2, len(mine), method="wilson"), abs=1e-12)
        assert row.p == pytest.approx(stats.binomtest(int(matched), int(matched + mismatched)).pvalue, rel=1e-9)
    assert table["p_holm"].to_numpy() == pytest.approx(multipletests(table["p"], method="holm")[1], rel=1e-12)


def test_mean_score_interval_agrees_with_a_bootstrap_over_participants_written_as_a_loop(simulated):
    table = appropriateness_scores(simulated, resamples=4000, seed=1)
    pages = appropriateness_pages(simulated)
    rng = np.random.default_rng(99)
    for row in table.itertuples():
        mine = pages[pages["system"] == row.system]
        assert row.mean_score == pytest.approx(mine["score"].mean(), abs=1e-12)
        by_participant = [group["score"].to_numpy() for _, group in mine.groupby("participant")]
        assert row.n_participants == len(by_participant)
        means = []
        for _ in range(4000):
            chosen = [by_participant[i] for i in rng.integers(0, len(by_participant), len(by_participant))]
            means.append(np.concatenate(chosen).mean())
        low, high = np.percentile(means, [2.5, 97.5])
        assert row.ci_low == pytest.approx(low, abs=0.02) and row.ci_high == pytest.approx(high, abs=0.02)
    again = appropriateness_scores(simulated, resamples=4000, seed=1)
    pd.testing.assert_frame_equal(table, again)  # seeded


def test_pairs_of_systems_equal_scipys_wilcoxon_on_participants_mean_scores_with_holm(simulated):
    table = score_pairs(simulated)
    assert len(table) == 6
    means = appropriateness_pages(simulated).pivot_table(index="participant", columns="system",
                                                         values="score", aggfunc="mean")
    for row in table.itertuples():
        both = means[[row.system_a, row.system_b]].dropna()
        d = both[row.system_a] - both[row.system_b]
        assert row.n_participants == len(both) and row.mean_diff == pytest.approx(d.mean(), abs=1e-12)
        reference = stats.wilcoxon(d, zero_method="wilcox", correction=False, method="asymptotic")
        assert row.p == pytest.approx(reference.pvalue, rel=1e-9)
    assert table["p_holm"].to_numpy() == pytest.approx(multipletests(table["p"], method="holm")[1], rel=1e-12)
    nat_chance = table[(table["system_a"] == "Chance") & (table["system_b"] == "NAT")].iloc[0]
    assert nat_chance["reject"] and nat_chance["higher"] == "NAT"


def test_simulated_participants_preferences_are_recovered_within_their_intervals(simulated):
    shares = matched_preference(simulated).set_index("system")
    scores = appropriateness_scores(simulated).set_index("system")
    for system, p in PREFER_MATCHED.items():
        share = p * (1 - NO_PREFERENCE) + NO_PREFERENCE / 2
        assert shares.at[system, "ci_low"] < share < shares.at[system, "ci_high"], system
        score = (2 * p - 1) * (1 - NO_PREFERENCE) * (1 + CLEAR)
        assert scores.at[system, "ci_low"] < score < scores.at[system, "ci_high"], system
    assert shares.at["NAT", "reject"] and shares.at["RNN", "reject"] and not shares.at["Chance", "reject"]


def test_preferring_the_mismatched_clip_of_an_attention_page_excludes_the_participant():
    rows = (page("careful", "q1", "BAD", "left", "left", 2) + page("careful", "q2", "A", "left", "right", 1)
            + page("careless", "q1", "BAD", "right", "left", 1) + page("careless", "q2", "A", "left", "left", 2)
            + page("unsure", "q1", "BAD", "left", "none"))
    flagged = apply_exclusions(validate_ratings(pd.DataFrame(rows).astype(str)))
    excluded = flagged.groupby("participant")["excluded_participant"].all()
    assert excluded.to_dict() == {"careful": False, "careless": True, "unsure": False}
    assert set(flagged.loc[flagged["excluded_participant"], "exclusion_reason"]) == {
        "preferred the mismatched clip of a BAD page"}


@pytest.mark.parametrize("change, message", [
    (lambda rows: rows[1].update(system="B"), "an appropriateness page shows one system twice, its matched and its "
                                              "mismatched clip; page 'q1' of participant 'p1' in task 'all' "
                                              "(first at row 1) shows two systems"),
    (lambda rows: rows[1].update(matched=True), "one matched clip (matched true) and one mismatched (false); page 'q1'"),
    (lambda rows: [r.update(strength=3) for r in rows], "five levels, a preference of strength 1 (slightly) or 2 "
                                                        "(clearly); row 1 gives strength 3"),
    (lambda rows: rows[0].update(matched="perhaps"), "column 'matched' must hold true/false; row 1 holds 'perhaps'"),
    (lambda rows: [r.pop("matched") for r in rows], "lacks the required column(s) matched"),
])
def test_a_malformed_appropriateness_table_is_refused_naming_the_page_or_row(change, message):
    rows = page("p1", "q1", "A", "left", "left", 2) + page("p1", "q2", "A", "right", "left", 1)
    change(rows)
    with pytest.raises(AnalysisInputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        validate_ratings(pd.DataFrame(rows).astype(str))


def test_both_figures_are_written_as_png_and_svg(simulated, tmp_path):
    from analysis.reports.design_plots import appropriateness_plots
    from analysis.reports.plots import save_figure

    figures = appropriateness_plots(matched_preference(simulated), appropriateness_scores(simulated, resamples=200),
                                    list(PREFER_MATCHED))
    written = [path for name, figure in figures.items() for path in save_figure(figure, tmp_path, name)]
    assert sorted(p.name for p in written) == ["appropriateness_scores.png", "appropriateness_scores.svg",
                                               "matched_preference.png", "matched_preference.svg"]
    assert "share preferring the matched clip" in (tmp_path / "matched_preference.svg").read_text()


def test_the_report_command_writes_an_appropriateness_report(tmp_path, capsys):
    from analysis.cli import main

    table = simulate_appropriateness({"NAT": 0.9, "MoGlow": 0.75, "RNN": 0.55}, n_participants=40,
                                     inattentive_share=0.15, seed=5)
    table.to_csv(tmp_path / "ratings.csv", index=False)
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "ratings.csv"), "--out", str(out)]) == 0, capsys.readouterr().err
    for name in ("matched_preference", "appropriateness_scores", "score_pairs", "side_bias", "exclusions"):
        assert (out / "tables" / f"{name}.csv").is_file(), name
    for name in ("matched_preference", "appropriateness_scores"):
        assert (out / "figures" / f"{name}.png").is_file() and (out / "figures" / f"{name}.svg").is_file()
    shares = pd.read_csv(out / "tables" / "matched_preference.csv")
    assert set(shares["system"]) == {"NAT", "MoGlow", "RNN"}  # the BAD pages are checks, not compared
    summary = (out / "summary.md").read_text()
    assert "who preferred the mismatched clip of any BAD page" in summary
    assert "preferred the mismatched clip of a BAD page" in summary  # some inattentive ones were caught
    assert "the mean appropriateness scores (-2 to +2, [95 % bootstrap CI over participants]) were NAT" in summary
