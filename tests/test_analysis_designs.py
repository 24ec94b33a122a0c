"""The ratings schema's designs: single tables read as before, side-by-side and pairwise
tables carry their page structure, and broken pages are refused with the row named."""

from __future__ import annotations

import io

import pandas as pd
import pytest

from analysis import AnalysisInputError, apply_exclusions, read_ratings
from analysis.designs import table_design

SINGLE_CSV = ("participant,system,stimulus,task,control_class,value,scale_min,scale_max,"
              "clip_duration_s,played_until_s\n"
              "p1,A,a1,human,held-out,4,1,5,10,10\n"
              "p1,NAT,n1,human,held-out,5,1,5,10,4\n")


def csv_of(rows: list[dict]) -> io.StringIO:
    return io.StringIO(pd.DataFrame(rows).to_csv(index=False))


def sbs_row(participant, page, system, value, position=1, **extra) -> dict:
    return {"design": "side-by-side", "participant": participant, "page": page, "system": system,
            "stimulus": f"{system}_{page}", "position": position, "value": value,
            "scale_min": 0, "scale_max": 100, **extra}


def pair_rows(participant, page, left, right, answer, **extra) -> list[dict]:
    return [{"design": "pairwise", "participant": participant, "page": page, "system": system,
             "stimulus": f"{system}_{page}", "side": side, "answer": answer, **extra}
            for side, system in (("left", left), ("right", right))]


def test_a_single_table_reads_as_before_with_no_design_columns_added():
    ratings = read_ratings(io.StringIO(SINGLE_CSV))
    assert list(ratings.columns) == ["participant", "system", "stimulus", "task", "control_class",
                                     "value", "scale_min", "scale_max", "clip_duration_s",
                                     "played_until_s", "answered_before_end"]
    assert ratings["value"].tolist() == [4, 5]
    assert ratings["answered_before_end"].tolist() == [False, True]
    assert table_design(ratings) == "single"
    explicit = read_ratings(io.StringIO(SINGLE_CSV.replace("participant,", "design,participant,")
                                        .replace("\np1,", "\nsingle,p1,")))
    pd.testing.assert_frame_equal(explicit.drop(columns="design"), ratings)


def test_a_side_by_side_table_keeps_page_and_position():
    rows = [sbs_row("p1", "c1", "A", 40, 2), sbs_row("p1", "c1", "NAT", 90, 1),
            sbs_row("p2", "c1", "A", 55, 1), sbs_row("p2", "c1", "NAT", 70, 2)]
    ratings = read_ratings(csv_of(rows))
    assert table_design(ratings) == "side-by-side"
    assert ratings["page"].tolist() == ["c1"] * 4  # page ids may repeat across participants
    assert ratings["position"].tolist() == [2, 1, 1, 2]
    assert ratings["value"].dtype == "int64"


def test_a_side_by_side_table_needs_a_page_column():
    rows = [sbs_row("p1", "c1", "A", 40)]
    del rows[0]["page"]
    with pytest.raises(AnalysisInputError, match="lacks the required column.*page.*side-by-side"):
        read_ratings(csv_of(rows))


def test_a_system_twice_on_one_page_is_refused_with_the_row():
    rows = [sbs_row("p1", "c1", "A", 40), sbs_row("p1", "c2", "A", 50, 1), sbs_row("p1", "c2", "A", 60, 2)]
    with pytest.raises(AnalysisInputError, match="'A' appears twice on page 'c2'.*row 2"):
        read_ratings(csv_of(rows))


def test_two_clips_at_one_position_of_a_page_are_refused():
    rows = [sbs_row("p1", "c1", "A", 40, 1), sbs_row("p1", "c1", "B", 50, 2), sbs_row("p1", "c1", "C", 60, 2)]
    with pytest.raises(AnalysisInputError, match="two clips share position 2 on page 'c1'.*row 2"):
        read_ratings(csv_of(rows))


def test_a_side_by_side_slider_value_outside_its_scale_is_refused():
    with pytest.raises(AnalysisInputError, match="outside their declared scale, first at row 2"):
        read_ratings(csv_of([sbs_row("p1", "c1", "A", 40, 1), sbs_row("p1", "c1", "B", 101, 2)]))


def test_a_pairwise_table_needs_no_value_and_normalises_its_answers():
    rows = pair_rows("p1", "q1", "A", "B", "Left") + pair_rows("p1", "q2", "B", "NAT", "none", strength="")
    rows[0]["strength"] = 2
    ratings = read_ratings(csv_of(rows))
    assert "value" not in ratings.columns
    assert ratings["answer"].tolist() == ["left", "left", "none", "none"]
    assert ratings["strength"].iloc[0] == 2
    assert ratings["strength"].isna().tolist() == [False, True, True, True]


@pytest.mark.parametrize(("change", "message"), [
    (lambda rows: rows[:3], "exactly two rows, one on each side; page 'q2'.*row 3"),
    (lambda rows: [*rows[:3], {**rows[3], "side": "left"}], "exactly two rows, one on each side"),
    (lambda rows: [*rows[:3], {**rows[3], "answer": "left"}], "same answer; page 'q2'"),
    (lambda rows: [*rows[:3], {**rows[3], "answer": "maybe"}], "'answer' must be one of left, right, none; row 4"),
    (lambda rows: [*rows[:3], {**rows[3], "side": "top"}], "'side' must be one of left, right; row 4"),
    (lambda rows: [*rows[:3], {**rows[3], "strength": "1.5"}], "'strength' must hold whole numbers from 1"),
    (lambda rows: [*rows[:2], *({**r, "answer": "none", "strength": 2} for r in rows[2:])],
     "'strength' qualifies a preference, but row 3 gives one with answer 'none'"),
])
def test_broken_pairwise_pages_are_refused_naming_page_and_row(change, message):
    rows = pair_rows("p1", "q1", "A", "B", "left") + pair_rows("p1", "q2", "A", "NAT", "right")
    with pytest.raises(AnalysisInputError, match=message):
        read_ratings(csv_of(change(rows)))


def test_unknown_and_mixed_designs_are_refused():
    rows = [sbs_row("p1", "c1", "A", 40), {**sbs_row("p1", "c1", "B", 40), "design": "mushra"}]
    with pytest.raises(AnalysisInputError, match="'design' must be one of single, side-by-side, pairwise, appropriateness; row 2"):
        read_ratings(csv_of(rows))
    rows[1]["design"] = "single"
    with pytest.raises(AnalysisInputError, match="mixes side-by-side, single"):
        read_ratings(csv_of(rows))


def test_preferring_the_attention_clip_excludes_the_participant_and_no_preference_does_not():
    rows = (pair_rows("careless", "q1", "BAD", "NAT", "left") + pair_rows("careless", "q2", "A", "B", "left")
            + pair_rows("unsure", "q1", "NAT", "BAD", "none") + pair_rows("careful", "q1", "NAT", "BAD", "left"))
    flagged = apply_exclusions(read_ratings(csv_of(rows)))
    excluded = flagged.groupby("participant")["excluded_participant"].all()
    assert excluded.to_dict() == {"careful": False, "careless": True, "unsure": False}
    assert set(flagged.loc[flagged["participant"] == "careless", "exclusion_reason"]) == {"preferred a BAD clip"}


def test_an_early_answer_discards_both_rows_of_its_pairwise_page():
    rows = (pair_rows("p1", "q1", "A", "B", "left", answered_before_end="false")
            + pair_rows("p1", "q2", "A", "B", "right", answered_before_end="false"))
    rows[3]["answered_before_end"] = "true"  # the right clip of q2 was not played to its end
    flagged = apply_exclusions(read_ratings(csv_of(rows)))
    assert flagged["discarded_early"].tolist() == [False, False, True, True]
    assert flagged["kept"].tolist() == [True, True, False, False]
