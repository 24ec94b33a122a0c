"""Results only where the data can carry them: below the minimums of `analysis.stats.minimums`
the models and bootstraps are not run and the report and command line say "too few
ratings"; intervals from few participants carry a warning."""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.stats.matching import appropriateness_scores, matched_preference
from analysis.rankings.bradley_terry import bradley_terry_scale
from analysis.cli import main
from analysis.ratings.exclusions import ExclusionRules, apply_exclusions, compared_ratings
from analysis.rankings.leaderboard import leaderboard
from analysis.stats.minimums import (BOOTSTRAP_MIN_PARTICIPANTS, INTERVAL_FEW_PARTICIPANTS, MODEL_MIN_PARTICIPANTS,
                               MODEL_MIN_RATINGS_PER_SYSTEM)
from analysis.stats.preferences import preference_pages, preference_pairs
from analysis.ratings.schema import validate_ratings
from analysis.ratings.report import build_report
from analysis.stats.within_page import median_and_mean
from analysis.ratings.simulate import simulate_appropriateness, simulate_pairwise, simulate_ratings, simulate_side_by_side
from analysis.reports.tables import FEW_PARTICIPANTS_MARK


def one_participants_ratings() -> pd.DataFrame:
    """Two ratings of NAT and two of A by one participant, with some spread."""
    table = simulate_ratings({"NAT": 4.2, "A": 3.0}, 400, control_classes=("c",), inattentive_share=0.0,
                             early_share=0.0, seed=1)
    rows = pd.concat([table[table["system"] == s].head(2) for s in ("NAT", "A")]).assign(participant="p0")
    return rows.assign(value=[5, 4, 3, 2])


def test_the_rater_models_command_says_too_few_ratings_instead_of_fitting_one_participants_four(tmp_path, capsys):
    path = tmp_path / "ratings.csv"
    one_participants_ratings().to_csv(path, index=False)
    assert main(["rater-models", str(path), "--out", str(tmp_path / "models")]) == 0
    said = capsys.readouterr().out
    assert (f"too few ratings: 4 from 1 participant (A has 2); a model needs at least {MODEL_MIN_PARTICIPANTS} "
            f"participants and {MODEL_MIN_RATINGS_PER_SYSTEM} ratings per system") in said
    assert not list((tmp_path / "models").glob("tables/crossed_mixed_*")), "no model of four ratings is written"
    assert not list((tmp_path / "models").glob("tables/ordinal_mixed_*"))


def test_the_report_fits_no_mixed_model_to_one_participant_and_says_why():
    report = build_report(one_participants_ratings())
    assert report.mixed.empty and report.rater_models.crossed.estimates.empty
    assert any(note.startswith("No mixed model for locomotion · c: too few ratings: 4 from 1 participant")
               for note in report.notes)


def test_table_2_marks_intervals_from_fewer_than_ten_participants_and_the_notes_say_so():
    ratings = simulate_ratings({"NAT": 4.2, "A": 3.0}, 300, control_classes=("c",), inattentive_share=0.0, seed=2)
    participants = ratings["participant"].nunique()
    assert MODEL_MIN_PARTICIPANTS <= participants < INTERVAL_FEW_PARTICIPANTS
    report = build_report(ratings)
    assert len(report.mixed), "enough participants for the mixed model"
    assert set(report.means["participants"]) <= set(range(MODEL_MIN_PARTICIPANTS, INTERVAL_FEW_PARTICIPANTS))
    assert all(f"fewer than {INTERVAL_FEW_PARTICIPANTS}" in w for w in report.means["warning"])
    assert all(cell.endswith(FEW_PARTICIPANTS_MARK) for cell in report.significance_display.to_numpy().ravel())
    assert any(note.startswith("The interval of A in locomotion · c is from ") for note in report.notes)


def test_many_participants_leave_the_intervals_unmarked():
    report = build_report(simulate_ratings({"NAT": 4.2, "A": 3.0}, 1200, control_classes=("c",),
                                           ratings_per_participant=40, inattentive_share=0.0, seed=2))
    assert (report.means["participants"] >= INTERVAL_FEW_PARTICIPANTS).all() and not report.means["warning"].any()
    assert not any(cell.endswith(FEW_PARTICIPANTS_MARK) for cell in report.significance_display.to_numpy().ravel())


def kept(table: pd.DataFrame) -> pd.DataFrame:
    rules = ExclusionRules()
    return compared_ratings(apply_exclusions(validate_ratings(table), rules), rules)


def test_a_bootstrap_over_two_participants_gives_no_interval_but_too_few_ratings():
    scores = appropriateness_scores(kept(simulate_appropriateness({"NAT": 0.8, "A": 0.6}, n_participants=2,
                                                                  inattentive_share=0.0, seed=3)))
    assert scores["ci_low"].isna().all() and scores["ci_high"].isna().all()
    assert set(scores["warning"]) == {f"too few ratings: from 2 participants; a bootstrap interval needs at least "
                                      f"{BOOTSTRAP_MIN_PARTICIPANTS} participants"}


def test_a_bootstrap_over_a_few_participants_warns_that_its_interval_rests_on_them():
    scores = appropriateness_scores(kept(simulate_appropriateness({"NAT": 0.8, "A": 0.6}, n_participants=6,
                                                                  inattentive_share=0.0, seed=3)))
    assert (scores["ci_high"] > scores["ci_low"]).all()
    assert set(scores["warning"]) == {"from 6 participants only (fewer than 10): the interval is less certain "
                                      "than it looks"}


def test_the_appropriateness_report_notes_the_missing_intervals(tmp_path, capsys):
    path = tmp_path / "ratings.csv"
    simulate_appropriateness({"NAT": 0.8, "A": 0.6}, n_participants=2, inattentive_share=0.0,
                             seed=3).to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 0
    said = capsys.readouterr().out
    assert "note: Appropriateness score of A in locomotion · held-out: too few ratings: from 2 participants" in said
    assert "[too few ratings]" in (tmp_path / "report" / "summary.md").read_text()


def test_a_leaderboard_of_two_participants_has_no_bootstrap_intervals_and_says_why():
    table, notes = leaderboard(kept(simulate_pairwise({"NAT": 1.0, "A": 0.0, "B": -0.5}, n_participants=2,
                                                      inattentive_share=0.0, seed=4)), resamples=200)
    assert len(table) and table["ci_low"].isna().all() and (table["resamples_used"] == 0).all()
    assert any(note.startswith("No intervals on the leaderboard for gesture · ") and "too few ratings: from 2 "
               "participants" in note for note in notes)
    assert not any("bootstrap resamples had a system" in note for note in notes)
    assert np.isfinite(table["elo"]).all()


def test_every_designs_interval_tables_warn_of_intervals_from_few_participants():
    sbs = kept(simulate_side_by_side({"NAT": 80, "A": 60}, n_participants=4, inattentive_share=0.0, seed=6))
    pairs = kept(simulate_pairwise({"NAT": 1.0, "A": 0.0}, n_participants=4, inattentive_share=0.0, seed=6))
    shown = kept(simulate_appropriateness({"NAT": 0.8, "A": 0.6}, n_participants=4, inattentive_share=0.0, seed=6))
    scale, _ = bradley_terry_scale(preference_pages(pairs))
    for table in (median_and_mean(sbs), preference_pairs(pairs), scale, matched_preference(shown)):
        assert len(table) and (table["participants"] == 4).all()
        assert set(table["warning"]) == {"from 4 participants only (fewer than 10): the interval is less certain "
                                         "than it looks"}
