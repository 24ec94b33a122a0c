"""Messages that name the real cause: a comparison graph of groups never compared is not
one where a group always won, and a pairwise table without a design column is told to
add that column, not value and scale columns, as is a side-by-side one, whose pages hold
several rows."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.rankings.bradley_terry import bradley_terry_scale, fit_bradley_terry
from analysis.cli import main
from analysis.designs import design_of
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import ExclusionRules, apply_exclusions, compared_ratings
from analysis.rankings.leaderboard import leaderboard
from analysis.stats.preferences import preference_pages
from analysis.ratings.schema import validate_ratings
from analysis.ratings.simulate import (
    simulate_appropriateness,
    simulate_pairwise,
    simulate_ratings,
    simulate_side_by_side,
)

NEVER_COMPARED = "groups never compared with each other ({A, B}; {C, D})"


def kept(table):
    rules = ExclusionRules()
    return compared_ratings(apply_exclusions(validate_ratings(table), rules), rules)


def two_apart():
    """A against B and C against D, each pair won both ways, and never a page across."""
    return simulate_pairwise({"A": 0.0, "B": 0.5, "C": 0.0, "D": 0.5}, n_participants=12,
                             pairs=[("A", "B"), ("C", "D")], inattentive_share=0.0, seed=5)


def test_bradley_terry_names_the_groups_never_compared():
    wins = np.array([[0, 3, 0, 0], [2, 0, 0, 0], [0, 0, 0, 4], [0, 0, 1, 0]], dtype=float)
    with pytest.raises(AnalysisInputError, match=r"2 groups never compared with each other \({A, B}; {C, D}\)"):
        fit_bradley_terry(wins, ["A", "B", "C", "D"])


def test_a_separated_graph_is_still_one_where_a_group_always_won():
    # A and B beat each other, and both always beat C and D, which beat each other: compared, never won.
    wins = np.array([[0, 3, 2, 2], [2, 0, 2, 2], [0, 0, 0, 4], [0, 0, 1, 0]], dtype=float)
    with pytest.raises(AnalysisInputError, match="groups of which one always beat the other") as refused:
        fit_bradley_terry(wins, ["A", "B", "C", "D"])
    assert "never compared" not in str(refused.value)


def test_the_pairwise_report_and_the_leaderboard_say_the_groups_were_never_compared():
    pages = kept(two_apart())
    _, notes = bradley_terry_scale(preference_pages(pages))
    assert any(NEVER_COMPARED in note for note in notes) and not any("always beat" in note for note in notes)
    table, notes = leaderboard(pages, resamples=50)
    assert table.empty and any(NEVER_COMPARED in note for note in notes)
    assert not any("always beat" in note for note in notes)


@pytest.mark.parametrize("simulate, design, own", [
    (lambda: simulate_pairwise({"A": 0.0, "B": 1.0}, n_participants=3), "pairwise", "page, side, answer"),
    (lambda: simulate_appropriateness({"A": 0.7}, n_participants=3), "appropriateness", "page, side, answer, matched"),
])
def test_a_table_of_another_design_without_its_design_column_is_told_to_add_that_column(simulate, design, own,
                                                                                      tmp_path, capsys):
    path = tmp_path / "ratings.csv"
    simulate().drop(columns=["design"]).to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 2
    error = capsys.readouterr().err
    assert (f"no 'design' column, so it was read as single ratings, which need value, scale_min, scale_max; its "
            f"columns {own} are those of the {design} design: add a column 'design' holding '{design}' on every "
            "row") in error
    assert not (tmp_path / "report").exists()


def test_a_side_by_side_table_without_its_design_column_is_refused_naming_the_file(tmp_path, capsys):
    path = tmp_path / "ratings.csv"
    simulate_side_by_side({"A": 40.0, "B": 60.0}, n_participants=6).drop(columns=["design"]).to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "Traceback" not in error
    assert (f"ratings table {path} has no 'design' column, so it would be read as single ratings, one clip per page; "
            "but its page 'c11' of participant 'p0' has 2 rows (first at row 1), so it looks like a side-by-side "
            "table: add a column 'design' holding 'side-by-side' on every row") in error
    assert not (tmp_path / "report").exists()


def test_a_single_table_without_a_design_column_reads_as_single_ratings_with_a_page_per_row():
    table = simulate_ratings({"A": 3.0, "B": 4.0}, n_ratings=60, ratings_per_participant=10)
    table["page"] = table.groupby("participant").cumcount() + 1  # page ids repeat across participants, not within
    ratings = validate_ratings(table)
    assert design_of(table).name == "single"
    assert len(ratings) == len(table) and ratings["page"].tolist() == table["page"].tolist()


def test_a_table_declared_single_may_share_its_pages():
    # The refusal's way out for a table whose page column means something else.
    table = simulate_ratings({"A": 3.0, "B": 4.0}, n_ratings=60, ratings_per_participant=10).assign(
        design="single", page="intro")
    assert design_of(table).name == "single" and len(validate_ratings(table)) == len(table)
