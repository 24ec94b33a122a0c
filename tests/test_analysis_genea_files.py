"""The GENEA leaderboard's vote files: read as they are, fitted as the project's own table
of the same votes, and written back byte for byte.

The files are written here the way GENEA's scripts write them: a pandas DataFrame of one
row per vote (``is_strong`` True, False or None) saved with ``to_csv(index=False)``.
"""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest

from analysis.cli import main
from analysis.designs import design_of
from analysis.errors import AnalysisInputError
from analysis.ratings.genea_files import genea_csv, genea_layout
from analysis.rankings.graded_votes import simulate_graded_pairwise
from analysis.rankings.leaderboard import leaderboard
from analysis.ratings.schema import read_ratings

STRENGTHS = {"NAT": 1.0, "A": 0.5, "B": 0.1, "C": -0.4}
REASONS = ["{}", "{'motion': ['hands', 'timing']}", "{'speech': ['rhythm']}"]
OTHER = ["", "the left one, \"stiff\"", "hands, then\nthe head"]


def project_table() -> pd.DataFrame:
    table = simulate_graded_pairwise(STRENGTHS, n_participants=30, pages_per_participant=12, seed=7)
    table.loc[table["participant"].isin(["p0", "p1"]), "strength"] = pd.NA  # plain answers
    return table


def genea_votes(table: pd.DataFrame) -> pd.DataFrame:
    """The same votes as GENEA's one row per vote, with seeded reasons."""
    left, right = table[table["side"] == "left"], table[table["side"] == "right"]
    rng = np.random.default_rng(3)
    winner = left["answer"].map({"left": "model_a", "right": "model_b", "none": "tie"}).to_numpy()
    strong = [None if pd.isna(s) else s == 2 for s in left["strength"]]
    return pd.DataFrame({
        "user": left["participant"].to_numpy(), "input_code": left["stimulus"].str.split("_").str[1].to_numpy(),
        "model_a": left["system"].to_numpy(), "model_b": right["system"].to_numpy(), "winner": winner,
        "is_strong": strong, "juiceOptions": rng.choice(REASONS, len(left)),
        "juiceOtherReason": rng.choice(OTHER, len(left))})


def write_genea(votes: pd.DataFrame, path, line_ending: str = "\n") -> bytes:
    votes.to_csv(path, index=False, lineterminator=line_ending)
    return path.read_bytes()


@pytest.mark.parametrize("line_ending", ["\n", "\r\n"])
def test_a_genea_battles_file_comes_back_from_genea_votes_byte_for_byte(tmp_path, line_ending):
    written = write_genea(genea_votes(project_table()), tmp_path / "battles.csv", line_ending)
    assert b'"hands, then\n' in written and b'""stiff""' in written  # the reasons need quoting
    assert main(["genea-votes", str(tmp_path / "battles.csv"), "--out", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "votes_genea.csv").read_bytes() == written


def test_a_genea_battles_file_is_fitted_as_the_same_votes_in_the_projects_table(tmp_path):
    table = project_table()
    write_genea(genea_votes(table), tmp_path / "battles.csv")
    genea = read_ratings(tmp_path / "battles.csv")
    assert design_of(genea).name == "pairwise" and len(genea) == len(table)
    own = read_ratings(io.StringIO(table.to_csv(index=False)))
    ours, _ = leaderboard(genea, resamples=300, seed=4)
    theirs, _ = leaderboard(own, resamples=300, seed=4)
    columns = ["system", "elo", "ci_low", "ci_high", "pages", "wins", "losses", "ties"]
    pd.testing.assert_frame_equal(ours[columns], theirs[columns])
    assert {"genea:juiceOptions", "genea:juiceOtherReason"} <= set(genea.columns)


def test_the_leaderboard_command_reads_a_genea_battles_file_as_it_is(tmp_path):
    write_genea(genea_votes(project_table()), tmp_path / "battles.csv")
    assert main(["leaderboard", str(tmp_path / "battles.csv"), "--out", str(tmp_path / "out"),
                 "--resamples", "50"]) == 0
    board = pd.read_csv(tmp_path / "out" / "tables" / "leaderboard.csv")
    assert sorted(board["system"]) == sorted(STRENGTHS) and (board["anchor"] == "NAT").all()


def test_a_projects_pairwise_table_is_written_as_genea_votes():
    table = read_ratings(io.StringIO(project_table().to_csv(index=False)))
    votes = pd.read_csv(io.StringIO(genea_csv(table)), dtype=str, keep_default_na=False)
    left = table[table["side"] == "left"].reset_index(drop=True)
    assert list(votes.columns) == ["user", "input_code", "model_a", "model_b", "winner", "is_strong"]
    assert (votes["user"] == left["participant"]).all() and (votes["model_a"] == left["system"]).all()
    expected = np.where(left["answer"] == "none", "",
                        left["strength"].map({2: "True", 1: "False"}).astype(object).fillna(""))
    assert list(votes["is_strong"]) == list(expected)
    assert list(votes["winner"]) == list(left["answer"].map({"left": "model_a", "right": "model_b", "none": "tie"}))


def mismatch_votes() -> pd.DataFrame:
    rows = []
    rng = np.random.default_rng(11)
    for user in range(12):
        for code in range(4):
            system = ["A", "B", "NAT"][code % 3]
            pair = [system, system + "_Mismatched"][:: 1 if rng.random() < 0.5 else -1]
            winner = rng.choice(["model_a", "model_b", "tie"], p=[0.45, 0.35, 0.2])
            rows.append({"user": f"u{user}", "input_code": f"seg{code}", "model_a": pair[0], "model_b": pair[1],
                         "winner": winner, "is_strong": False if winner == "tie" else bool(rng.random() < 0.5),
                         "juiceOptions": "{}", "juiceOtherReason": ""})
    return pd.DataFrame(rows)


def test_a_genea_mismatch_file_reads_as_appropriateness_and_comes_back_byte_for_byte(tmp_path):
    written = write_genea(mismatch_votes(), tmp_path / "mismatch.csv")
    table = read_ratings(tmp_path / "mismatch.csv")
    assert design_of(table).name == "appropriateness"
    first = table.iloc[:2]
    assert set(first["system"]) == {first["genea:model_a"].iloc[0].removesuffix("_Mismatched")}
    assert list(first["matched"]) == [not first["genea:model_a"].iloc[0].endswith("_Mismatched"),
                                      not first["genea:model_b"].iloc[0].endswith("_Mismatched")]
    assert genea_csv(table, genea_layout(written.decode())).encode() == written
    assert main(["report", str(tmp_path / "mismatch.csv"), "--out", str(tmp_path / "out")]) == 0


@pytest.mark.parametrize("column, value, why", [
    ("winner", "model_c", "'winner': 'model_c' is none of model_a, model_b, tie"),
    ("is_strong", "yes", "'is_strong': 'yes' is not True, False or empty"),
    ("model_b", "", "'model_b': '' is empty"),
])
def test_a_bad_genea_vote_is_refused_naming_file_line_and_column(tmp_path, capsys, column, value, why):
    votes = genea_votes(project_table())
    votes[column] = votes[column].astype(object)
    votes.loc[2, column] = value
    write_genea(votes, tmp_path / "battles.csv")
    lines_before = sum(text.count("\n") for text in votes["juiceOtherReason"].iloc[:2])
    assert main(["leaderboard", str(tmp_path / "battles.csv"), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert f"battles.csv, line {4 + lines_before}, column {why}" in error
    assert not (tmp_path / "out").exists()


def test_a_mismatch_page_without_its_mismatched_clip_is_refused():
    votes = mismatch_votes()
    votes.loc[5, "model_b"] = "C"
    with pytest.raises(AnalysisInputError, match=r"line 7, column 'model_b'.*no mismatch page"):
        read_ratings(io.StringIO(votes.to_csv(index=False)))


def test_a_pairwise_table_without_its_design_column_is_told_to_add_one():
    table = project_table().drop(columns="design")
    with pytest.raises(AnalysisInputError, match="no 'design' column.*add a column 'design' holding 'pairwise'"):
        read_ratings(io.StringIO(table.to_csv(index=False)))


def test_a_genea_file_missing_a_vote_column_is_told_which():
    votes = genea_votes(project_table()).drop(columns="is_strong")
    with pytest.raises(AnalysisInputError, match="as a GENEA vote file it lacks is_strong"):
        read_ratings(io.StringIO(votes.to_csv(index=False)))
