"""The leaderboard against independent computations.

References: statsmodels' GLM (binomial, ``freq_weights``) on one row per weighted vote
for the weighted Bradley-Terry fit, the project's MM fit (`analysis.rankings.bradley_terry`) for
plain answers, an independently written page-level Davidson likelihood maximised by
scipy, the bootstrap's resamples refitted one by one from the resampled participants'
pages, and a simulation of many studies for the intervals' coverage.
"""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from scipy import optimize

from analysis.rankings.bradley_terry import fit_bradley_terry, win_matrix
from analysis.cli import main
from analysis.errors import AnalysisInputError
from analysis.rankings.graded_votes import simulate_graded_pairwise
from analysis.rankings.leaderboard import (ELO_PER_LOG_ODDS, INTERVAL_WARNING_PARTICIPANTS, battles, fit_votes,
                                  leaderboard, pair_votes, participant_resamples, vote_pages)
from analysis.reports.leaderboard_report import build_leaderboard, leaderboard_tables, leaderboard_text
from analysis.stats.minimums import few_participants_warning
from analysis.stats.preferences import preference_pages
from analysis.ratings.schema import read_ratings
from analysis.ratings.simulate import simulate_pairwise

STRENGTHS = {"NAT": 1.0, "A": 0.5, "B": 0.2, "C": -0.1, "D": -0.6}


def as_read(table: pd.DataFrame) -> pd.DataFrame:
    """The table as `read_ratings` returns it from the CSV a study exports."""
    return read_ratings(io.StringIO(table.to_csv(index=False)))


@pytest.fixture(scope="module")
def graded() -> pd.DataFrame:
    table = simulate_graded_pairwise(STRENGTHS, n_participants=40, pages_per_participant=15, seed=5)
    plain = table["participant"].isin(["p0", "p1", "p2"])  # some pages without a strength
    table.loc[plain, "strength"] = pd.NA
    return as_read(table)


def glm_elo(pages: pd.DataFrame, systems: list[str], anchor: str) -> pd.Series:
    """Weighted logistic regression of the votes: a row per vote, y = 1 when the left clip
    won, x = e_left - e_right without the anchor's column, frequency weight = the vote's
    weight (2 per degree of strength, 4 without one); a tie is two rows of weight 1, one
    won by each side."""
    rows, outcome, weight = [], [], []
    for page in pages.itertuples(index=False):
        x = np.zeros(len(systems))
        x[systems.index(page.system_left)], x[systems.index(page.system_right)] = 1.0, -1.0
        if page.answer == "none":
            rows += [x, x]
            outcome += [1.0, 0.0]
            weight += [1.0, 1.0]
        else:
            rows.append(x)
            outcome.append(1.0 if page.answer == "left" else 0.0)
            weight.append(4.0 if pd.isna(page.strength) else 2.0 * page.strength)
    a = systems.index(anchor)
    fit = sm.GLM(np.array(outcome), np.delete(np.array(rows), a, axis=1),
                 family=sm.families.Binomial(), freq_weights=np.array(weight)).fit(tol=1e-13)
    return pd.Series(1000 + ELO_PER_LOG_ODDS * np.insert(fit.params, a, 0.0), index=systems)


def test_elo_differences_equal_a_weighted_logistic_regression(graded):
    board, notes = leaderboard(graded, resamples=0)
    assert notes == []
    ours = board.set_index("system")["elo"]
    reference = glm_elo(preference_pages(graded).merge(
        graded.loc[graded["side"] == "left", ["participant", "page", "strength"]]), sorted(STRENGTHS), "NAT")
    np.testing.assert_allclose(ours[reference.index], reference, atol=1e-6)
    assert ours["NAT"] == 1000.0 and list(board["system"]) == list(ours.sort_values(ascending=False).index)
    assert (board["model"] == "bradley-terry").all() and (board["anchor"] == "NAT").all()


def test_plain_answers_count_as_clear_wins_and_give_the_plain_bradley_terry_fit():
    plain = as_read(simulate_pairwise(STRENGTHS, n_participants=30, no_preference_share=0.0,
                                      inattentive_share=0.0, early_share=0.0, seed=2))
    board, _ = leaderboard(plain, resamples=0)
    systems, wins = win_matrix(preference_pages(plain))
    centred, _, _ = fit_bradley_terry(wins)
    expected = pd.Series(ELO_PER_LOG_ODDS * (centred - centred[systems.index("NAT")]) + 1000, index=systems)
    np.testing.assert_allclose(board.set_index("system")["elo"][systems], expected, atol=1e-6)
    clear = plain.assign(strength=np.where(plain["answer"] == "none", pd.NA, 2))
    np.testing.assert_allclose(leaderboard(clear, resamples=0)[0]["elo"], board["elo"], atol=1e-9)


def davidson_page_likelihood(theta: np.ndarray, pages: pd.DataFrame, systems: list[str]) -> float:
    """Minus the log-likelihood, page by page: P(left) = pi_l / D, P(right) = pi_r / D,
    P(tie) = nu sqrt(pi_l pi_r) / D, D = pi_l + pi_r + nu sqrt(pi_l pi_r), a page
    weighted 4 (clear or plain), 2 (slight) or 2 (tie); system 0 fixed at b = 0."""
    b = np.r_[0.0, theta[:-1]]
    nu = np.exp(theta[-1])
    total = 0.0
    for page in pages.itertuples(index=False):
        pl, pr = np.exp(b[systems.index(page.system_left)]), np.exp(b[systems.index(page.system_right)])
        d = pl + pr + nu * np.sqrt(pl * pr)
        if page.answer == "none":
            total += 2.0 * np.log(nu * np.sqrt(pl * pr) / d)
        else:
            weight = 2.0 if not pd.isna(page.strength) and page.strength == 1 else 4.0
            total += weight * np.log((pl if page.answer == "left" else pr) / d)
    return -total


def test_davidson_fit_maximises_an_independently_written_likelihood(graded):
    pages = vote_pages(graded)
    systems = sorted(STRENGTHS)
    fit = fit_votes(pair_votes(pages, systems), "davidson", resamples=0)
    ours = np.r_[fit.log_strength[1:], np.log(fit.tie_parameter)]
    found = optimize.minimize(davidson_page_likelihood, np.zeros(len(systems)), args=(pages, systems),
                              method="BFGS", options={"gtol": 1e-9})
    np.testing.assert_allclose(ours, found.x, atol=1e-5)
    assert davidson_page_likelihood(ours, pages, systems) <= found.fun + 1e-9
    gradient = optimize.approx_fprime(ours, davidson_page_likelihood, 1e-6, pages, systems)
    assert np.abs(gradient).max() < 1e-3  # central of a sum over 600 pages: zero up to rounding


def test_each_bootstrap_resample_equals_a_fit_of_the_resampled_participants(graded):
    pages = vote_pages(graded)
    systems = sorted(STRENGTHS)
    votes = pair_votes(pages, systems)
    fit = fit_votes(votes, resamples=3, seed=11)
    participants = pd.factorize(pages["participant"])[1]
    for counts, resampled in zip(participant_resamples(len(participants), 3, 11), fit.resampled):
        drawn = pd.concat([pages[pages["participant"] == p]
                           for p, n in zip(participants, counts.astype(int)) for _ in range(n)])
        reference = glm_elo(drawn, systems, systems[0])
        np.testing.assert_allclose(1000 + ELO_PER_LOG_ODDS * resampled, reference, atol=1e-6)


def test_the_bootstrap_is_reproducible_by_seed(graded):
    first, _ = leaderboard(graded, resamples=300, seed=7)
    again, _ = leaderboard(graded, resamples=300, seed=7)
    other, _ = leaderboard(graded, resamples=300, seed=8)
    pd.testing.assert_frame_equal(first, again)
    assert not np.allclose(first["ci_low"][first["system"] != "NAT"], other["ci_low"][other["system"] != "NAT"])
    assert (first["ci_low"] <= first["elo"]).all() and (first["elo"] <= first["ci_high"]).all()


def test_the_intervals_cover_the_true_elo_at_their_nominal_rate():
    truth = 1000 + ELO_PER_LOG_ODDS * (pd.Series(STRENGTHS) - STRENGTHS["NAT"])
    covered = []
    for study in range(60):
        table = as_read(simulate_graded_pairwise(STRENGTHS, n_participants=25, pages_per_participant=12,
                                                 seed=100 + study))
        board, _ = leaderboard(table, resamples=400, seed=study)
        board = board.set_index("system").drop("NAT")
        covered += list((board["ci_low"] <= truth[board.index]) & (truth[board.index] <= board["ci_high"]))
    # 240 intervals of 95 %: a binomial 95 % range is about 0.92 to 0.98
    assert 0.90 <= np.mean(covered) <= 0.99


def with_three_degrees(graded: pd.DataFrame) -> pd.DataFrame:
    """The graded table as a study asking three degrees of preference would store it: a
    clear preference on every third page made the strongest degree, 3."""
    table = graded.copy()
    page_number = table["page"].str[1:].astype(int)
    table.loc[(table["strength"] == 2) & (page_number % 3 == 0), "strength"] = 3
    return as_read(table)


def test_a_three_degree_study_counts_two_wins_per_degree_as_a_weighted_logistic_regression(graded):
    three = with_three_degrees(graded)
    assert set(three["strength"].dropna()) == {1, 2, 3}
    board, notes = leaderboard(three, resamples=0)
    assert notes == []
    reference = glm_elo(preference_pages(three).merge(
        three.loc[three["side"] == "left", ["participant", "page", "strength"]]), sorted(STRENGTHS), "NAT")
    np.testing.assert_allclose(board.set_index("system")["elo"][reference.index], reference, atol=1e-6)
    assert not np.allclose(board.set_index("system")["elo"][reference.index],
                           leaderboard(graded, resamples=0)[0].set_index("system")["elo"][reference.index])


def test_a_three_degree_study_s_report_states_the_weights(graded, tmp_path):
    path = tmp_path / "ratings.csv"
    with_three_degrees(graded).to_csv(path, index=False)
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out)]) == 0
    assert (out / "tables" / "leaderboard.csv").is_file() and (out / "figures" / "win_fraction.svg").is_file()
    assert "a preference of strength k counts 2k wins of the preferred system" in (out / "summary.md").read_text()


def test_a_strength_that_is_not_a_whole_number_from_one_is_refused_naming_its_row(graded):
    broken = graded.copy()
    broken["strength"] = broken["strength"].astype("Float64")
    broken.loc[7, "strength"] = 1.5
    with pytest.raises(AnalysisInputError, match="must be a whole number from 1 .slightly better.* row 8 holds 1.5"):
        leaderboard(broken)


def test_a_system_that_never_lost_is_noted_and_left_off():
    rows = []
    for i, (left, right, answer) in enumerate([("NAT", "A", "left"), ("A", "NAT", "right"),
                                              ("A", "B", "left"), ("B", "A", "left")]):
        rows += [{"task": "t", "control_class": "c", "participant": "p", "page": f"q{i}",
                  "system": s, "side": side, "answer": answer}
                 for side, s in (("left", left), ("right", right))]
    board, notes = leaderboard(pd.DataFrame(rows), resamples=10)
    assert board.empty
    assert notes == ["No leaderboard for t · c: NAT never lost and no system never won a vote, so "
                     "their strengths are unbounded."]


def test_without_the_natural_system_the_mean_sits_at_1000(graded):
    no_nat = graded[~graded.groupby(["participant", "page"])["system"].transform(lambda s: (s == "NAT").any())]
    board, _ = leaderboard(no_nat, resamples=50)
    assert (board["anchor"] == "mean").all() and board["elo"].mean() == pytest.approx(1000.0)
    anchored, _ = leaderboard(no_nat, anchor="B", resamples=50)
    assert anchored.set_index("system").loc["B", ["elo", "ci_low", "ci_high"]].tolist() == [1000.0] * 3
    differences = board.set_index("system")["elo"] - anchored.set_index("system")["elo"]
    assert np.ptp(differences) == pytest.approx(0.0, abs=1e-9)  # the anchor shifts, never stretches


def test_battles_and_win_fractions_count_pages_by_hand():
    rows = []
    for i, (left, right, answer) in enumerate([("A", "B", "left"), ("B", "A", "left"), ("A", "B", "none"),
                                              ("A", "B", "left"), ("C", "A", "right")]):
        rows += [{"task": "t", "control_class": "c", "participant": "p", "page": f"q{i}",
                  "system": s, "side": side, "answer": answer}
                 for side, s in (("left", left), ("right", right))]
    table = battles(pd.DataFrame(rows)).set_index(["system", "opponent"])
    assert table.loc[("A", "B"), ["battles", "wins", "ties"]].tolist() == [4, 2, 1]
    assert table.loc[("A", "B"), "win_fraction"] == pytest.approx(2 / 3)
    assert table.loc[("B", "A"), "win_fraction"] == pytest.approx(1 / 3)
    assert table.loc[("A", "C"), "win_fraction"] == 1.0 and table.loc[("C", "A"), "wins"] == 0


def test_the_command_writes_leaderboard_heat_maps_and_says_which_model(graded, tmp_path):
    path = tmp_path / "ratings.csv"
    graded.to_csv(path, index=False)
    out = tmp_path / "board"
    assert main(["leaderboard", str(path), "--out", str(out), "--model", "davidson",
                 "--resamples", "200", "--seed", "3"]) == 0
    for name in ("leaderboard", "battles", "side_bias"):
        assert all((out / "tables" / f"{name}.{fmt}").is_file() for fmt in ("csv", "md", "tex", "json"))
    for name in ("win_fraction", "battles"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 0
        assert (out / "figures" / f"{name}.svg").stat().st_size > 0
    summary = (out / "summary.md").read_text()
    assert "Davidson's model, in which a tie is an outcome of its own" in summary
    assert "200 bootstrap resamples of the participants (seed 3)" in summary
    written = pd.read_csv(out / "tables" / "leaderboard.csv")
    assert set(written["model"]) == {"davidson"} and written["tie_parameter"].nunique() == 1


def test_the_command_refuses_a_table_of_another_design_and_writes_nothing(tmp_path, capsys):
    path = tmp_path / "ratings.csv"
    pd.DataFrame({"participant": ["p1", "p1"], "system": ["A", "B"], "stimulus": ["a", "b"],
                  "value": [3, 4], "scale_min": 1, "scale_max": 5}).to_csv(path, index=False)
    assert main(["leaderboard", str(path), "--out", str(tmp_path / "board")]) == 2
    assert "leaderboard analyses pairwise tables" in capsys.readouterr().err
    assert not (tmp_path / "board").exists()


def test_the_pairwise_report_gains_the_leaderboard_heat_maps_and_paragraph(graded, tmp_path):
    path = tmp_path / "ratings.csv"
    graded.to_csv(path, index=False)
    out = tmp_path / "report"
    assert main(["report", str(path), "--out", str(out)]) == 0
    for name in ("leaderboard", "battles"):
        assert (out / "tables" / f"{name}.csv").is_file()
    for name in ("win_fraction", "battles"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 0
    board = pd.read_csv(out / "tables" / "leaderboard.csv")
    assert (board["resamples"] == 10_000).all() and set(board["anchor"]) == {"NAT"}
    summary = (out / "summary.md").read_text()
    assert "**Leaderboard, gesture · held-out.**" in summary and "weighted Bradley-Terry model" in summary


def test_every_leaderboard_table_states_its_anchor_and_origin(graded, tmp_path):
    path = tmp_path / "ratings.csv"
    graded.to_csv(path, index=False)
    out = tmp_path / "board"
    assert main(["leaderboard", str(path), "--out", str(out), "--resamples", "50"]) == 0
    written = pd.read_csv(out / "tables" / "leaderboard.csv")
    assert set(written["anchor"]) == {"NAT"} and set(written["origin"]) == {1000}
    for fmt in ("md", "tex"):
        assert "Elo with NAT at 1000, 400 points odds of 10 to 1" in (out / "tables" / f"leaderboard.{fmt}").read_text()
    no_nat = graded[~graded.groupby(["participant", "page"])["system"].transform(lambda s: (s == "NAT").any())]
    no_nat.to_csv(path, index=False)
    assert main(["leaderboard", str(path), "--out", str(tmp_path / "mean"), "--resamples", "50"]) == 0
    assert "Elo with the systems' mean at 1000" in (tmp_path / "mean" / "tables" / "leaderboard.md").read_text()


def test_intervals_from_fewer_than_ten_participants_are_flagged_once_by_the_reports_warning_column(graded):
    few = graded[graded["participant"].isin([f"p{i}" for i in range(3, 3 + INTERVAL_WARNING_PARTICIPANTS - 1)])]
    board, notes = leaderboard(few, resamples=50)
    assert "few_participants" not in board.columns  # one flag: the warning every interval table carries
    assert set(board["warning"]) == {few_participants_warning(INTERVAL_WARNING_PARTICIPANTS - 1)} != {""}
    assert set(board["participants"]) == {INTERVAL_WARNING_PARTICIPANTS - 1}
    assert any(f"come from {INTERVAL_WARNING_PARTICIPANTS - 1} participants, fewer than 10" in n for n in notes)
    enough, notes = leaderboard(graded[graded["participant"].isin([f"p{i}" for i in range(3, 13)])], resamples=50)
    assert set(enough["warning"]) == {""} and not any("fewer than 10" in n for n in notes)
    assert "intervals from fewer than 10 participants are rough (warning)" in \
        leaderboard_tables(build_leaderboard(few, resamples=50))["leaderboard"][0]
    text = leaderboard_text(build_leaderboard(few, resamples=50))
    assert "these intervals understate the uncertainty" in text
