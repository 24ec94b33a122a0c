"""Reasons with the votes: each system's reason counts from pages built by hand (the
counts worked out here page by page), ties counted apart, GENEA's juiceOptions read, and
the reasons carried through the report and the GENEA vote file."""

from __future__ import annotations

import io

import pandas as pd
import pytest

from analysis.cli import main
from analysis.ratings.genea_files import genea_csv
from analysis.ratings.schema import read_ratings
from analysis.reports.reasons import OTHER, options_text, read_options, reason_counts

SMOOTH, GESTURES, UNREAL = "Motion smoothness", "Recognisable gestures", "Unrealistic motion"


def pairwise(pages: list[tuple[str, str, str, str, list[str], str]]) -> pd.DataFrame:
    """Pages (participant, left system, right system, answer, ticked reasons, other words) as a ratings table."""
    rows = []
    for number, (participant, left, right, answer, ticked, other) in enumerate(pages, start=1):
        for side, system in (("left", left), ("right", right)):
            rows.append({"design": "pairwise", "participant": participant, "page": str(number), "system": system,
                         "stimulus": f"{system}-{number}", "side": side, "answer": answer, "strength": "",
                         "juiceOptions": options_text(ticked), "juiceOtherReason": other})
    return read_ratings(io.StringIO(pd.DataFrame(rows).to_csv(index=False)))


PAGES = [
    ("p1", "A", "B", "left", [SMOOTH], ""),
    ("p1", "B", "A", "right", [SMOOTH, GESTURES], ""),
    ("p2", "A", "B", "right", [UNREAL], "arms too stiff"),
    ("p2", "B", "A", "none", [UNREAL], ""),
    ("p3", "A", "B", "left", [], ""),
]


def counts_of(table: pd.DataFrame) -> dict[tuple[str, str], tuple[int, int, int]]:
    counts, notes = reason_counts(table)
    assert notes == []
    return {(r.system, r.reason): (r.count, r.pages, r.ties) for r in counts.itertuples(index=False)}


def test_a_reason_counts_for_the_system_the_vote_chose_and_a_ties_reasons_for_both_apart():
    counts = counts_of(pairwise(PAGES))
    # A was chosen on pages 1, 2 and 5; B on page 3 (with "Other" words); page 4 is a tie of A and B.
    assert counts == {
        ("A", SMOOTH): (2, 3, 0), ("A", GESTURES): (1, 3, 0), ("A", UNREAL): (0, 3, 1), ("A", OTHER): (0, 3, 0),
        ("B", SMOOTH): (0, 1, 0), ("B", GESTURES): (0, 1, 0), ("B", UNREAL): (1, 1, 1), ("B", OTHER): (1, 1, 0)}
    table, _ = reason_counts(pairwise(PAGES))
    share = table.set_index(["system", "reason"])["share"]
    assert share[("A", SMOOTH)] == pytest.approx(2 / 3) and share[("B", OTHER)] == 1.0


def test_a_side_by_side_page_chooses_its_top_rated_clip_and_a_shared_top_is_a_tie():
    rows = []
    for page, values, ticked in ((1, {"A": 80, "B": 40, "C": 10}, [SMOOTH]),
                                 (2, {"A": 70, "B": 70, "C": 10}, [GESTURES]),
                                 (3, {"A": 20, "B": 30, "C": 90}, [SMOOTH, GESTURES])):
        for position, (system, value) in enumerate(values.items(), start=1):
            rows.append({"design": "side-by-side", "participant": "p1", "page": str(page), "position": position,
                         "system": system, "stimulus": f"{system}-{page}", "value": value, "scale_min": 0,
                         "scale_max": 100, "juiceOptions": options_text(ticked), "juiceOtherReason": ""})
    counts = counts_of(read_ratings(io.StringIO(pd.DataFrame(rows).to_csv(index=False))))
    assert counts == {("A", SMOOTH): (1, 1, 0), ("A", GESTURES): (0, 1, 1), ("B", SMOOTH): (0, 0, 0),
                      ("B", GESTURES): (0, 0, 1), ("C", SMOOTH): (1, 1, 0), ("C", GESTURES): (1, 1, 0)}


def test_genea_options_are_read_from_their_dict_of_lists_and_an_unreadable_cell_is_noted_not_counted():
    assert read_options("{'motion': ['hands', 'timing'], 'speech': ['rhythm']}") == ["hands", "timing", "rhythm"]
    assert read_options("{}") == [] and read_options("") == [] and read_options("['a', 'a ']") == ["a"]
    assert read_options(options_text([SMOOTH, OTHER])) == [SMOOTH, OTHER]
    for bad in ("{'motion': [1]}", "__import__('os')", "{'a': "):
        with pytest.raises(ValueError):
            read_options(bad)
    table = pairwise(PAGES)
    table.loc[table["page"] == "1", "juiceOptions"] = "not a dict"
    counts, notes = reason_counts(table)
    assert notes == ["Reasons of participant p1's page 1: juiceOptions 'not a dict' is not a dict or list of "
                     "options; its options are not counted."]
    assert counts.set_index(["system", "reason"]).loc[("A", SMOOTH), "count"] == 1  # page 2's only


def test_the_report_has_the_reason_table_and_its_plot_and_the_genea_file_carries_the_reasons(tmp_path):
    table = pairwise(PAGES * 4)  # enough pages for the pairwise tables
    path = tmp_path / "ratings.csv"
    table.to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 0
    written = pd.read_csv(tmp_path / "report" / "tables" / "reasons.csv")
    assert written.set_index(["system", "reason"]).loc[("A", SMOOTH), "count"] == 8
    assert "Reasons given per system" in (tmp_path / "report" / "tables" / "reasons.md").read_text()
    assert (tmp_path / "report" / "figures" / "reasons.png").stat().st_size > 0
    votes = pd.read_csv(io.StringIO(genea_csv(table)), dtype=str, keep_default_na=False)
    assert list(votes.columns)[-2:] == ["juiceOptions", "juiceOtherReason"]
    assert votes["juiceOtherReason"].iloc[2] == "arms too stiff"
    assert read_options(votes["juiceOptions"].iloc[1]) == [SMOOTH, GESTURES]
    (tmp_path / "votes.csv").write_text(genea_csv(table))  # GENEA's file read back: the same counts
    assert reason_counts(read_ratings(tmp_path / "votes.csv"))[0].equals(reason_counts(table)[0])


def test_the_leaderboard_of_a_genea_battles_file_counts_its_reasons_per_system(tmp_path):
    table = pairwise(PAGES * 4)
    (tmp_path / "battles.csv").write_text(genea_csv(table))
    assert main(["leaderboard", str(tmp_path / "battles.csv"), "--out", str(tmp_path / "out"),
                 "--resamples", "20"]) == 0
    written = pd.read_csv(tmp_path / "out" / "tables" / "reasons.csv").set_index(["system", "reason"])
    assert (written.loc[("A", SMOOTH), "count"], written.loc[("B", OTHER), "count"]) == (8, 4)
    assert written.loc[("A", UNREAL), "ties"] == written.loc[("B", UNREAL), "ties"] == 4
    assert (tmp_path / "out" / "figures" / "reasons.svg").stat().st_size > 0
