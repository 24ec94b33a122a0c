"""Ratings schema, validation of bad input, and the MoGlow Sec. 5.2 exclusion rules."""

from __future__ import annotations

import io

import pandas as pd
import pytest

from analysis import AnalysisInputError, ExclusionRules, apply_exclusions, exclusion_summary, read_ratings
from analysis.ratings.exclusions import exclusion_notes, scaled_threshold


def ratings_csv(rows: list[dict]) -> io.StringIO:
    return io.StringIO(pd.DataFrame(rows).to_csv(index=False))


def rating(participant, system, value, stimulus=None, task="loco", scale=(1, 5), **extra) -> dict:
    return {"participant": participant, "system": system, "stimulus": stimulus or f"{system}_1",
            "task": task, "control_class": "held-out", "value": value,
            "scale_min": scale[0], "scale_max": scale[1], **extra}


def test_minimal_schema_is_enough_and_fills_task_and_control_class():
    rows = [{"participant": "p1", "system": "A", "stimulus": "s1", "value": 3,
             "scale_min": 1, "scale_max": 5}]
    df = read_ratings(ratings_csv(rows))
    assert df.loc[0, "task"] == "all" and df.loc[0, "control_class"] == "all"
    assert "answered_before_end" not in df.columns


def test_missing_columns_are_named():
    with pytest.raises(AnalysisInputError, match="value, scale_max"):
        read_ratings(io.StringIO("participant,system,stimulus,scale_min\np,A,s,1\n"))


def test_values_outside_the_declared_scale_are_rejected_with_the_row():
    rows = [rating("p1", "A", 3), rating("p1", "B", 6)]
    with pytest.raises(AnalysisInputError, match="outside their declared scale, first at row 2"):
        read_ratings(ratings_csv(rows))


def test_non_integer_values_are_rejected():
    with pytest.raises(AnalysisInputError, match="integers"):
        read_ratings(ratings_csv([rating("p1", "A", "3.5")]))


def test_scales_mixed_within_a_task_are_rejected():
    rows = [rating("p1", "A", 3), rating("p2", "A", 7, scale=(1, 10))]
    with pytest.raises(AnalysisInputError, match="mix rating scales"):
        read_ratings(ratings_csv(rows))


def test_early_answers_come_from_timestamps_when_no_flag_is_given():
    rows = [rating("p1", "A", 3, shown_at="2024-05-01T10:00:00Z", answered_at="2024-05-01T10:00:04Z",
                   clip_duration_s=10),
            rating("p1", "A", 3, stimulus="A_2", shown_at="2024-05-01T10:01:00Z",
                   answered_at="2024-05-01T10:01:12Z", clip_duration_s=10)]
    df = read_ratings(ratings_csv(rows))
    assert df["answered_before_end"].tolist() == [True, False]


def test_thresholds_scale_linearly_with_the_rating_range():
    assert scaled_threshold(4.0, 1, 5) == 4.0
    assert scaled_threshold(4.0, 1, 10) == pytest.approx(7.75)
    assert scaled_threshold(2.0, 1, 10) == pytest.approx(3.25)
    assert scaled_threshold(4.0, 0, 100) == pytest.approx(75.0)


def test_exclusions_flag_participants_and_early_answers_without_deleting():
    rows = [
        rating("good", "NAT", 4), rating("good", "BAD", 1), rating("good", "A", 3),
        rating("bad_check", "BAD", 4), rating("bad_check", "A", 5),
        rating("nat_low", "NAT", 1), rating("nat_low", "A", 2),
        rating("hasty", "A", 2, answered_before_end=True), rating("hasty", "NAT", 5),
    ]
    rows = [{**r, "answered_before_end": r.get("answered_before_end", False)} for r in rows]
    flagged = apply_exclusions(read_ratings(ratings_csv(rows)))
    assert len(flagged) == len(rows)
    by = flagged.groupby("participant")
    assert by["excluded_participant"].all().to_dict() == {
        "bad_check": True, "good": False, "hasty": False, "nat_low": True}
    assert flagged["discarded_early"].sum() == 1
    summary = exclusion_summary(flagged).iloc[0]
    assert summary["participants_total"] == 4 and summary["participants_removed"] == 2
    assert summary["ratings_collected"] == 9
    assert summary["discarded_participant"] == 4 and summary["discarded_early"] == 1
    assert summary["ratings_kept"] == 4
    assert summary["discarded_participant"] + summary["discarded_early"] + summary["ratings_kept"] == 9


def test_on_a_ten_point_scale_bad_at_eight_excludes_and_seven_does_not():
    rows = [rating("p7", "BAD", 7, scale=(1, 10)), rating("p8", "BAD", 8, scale=(1, 10)),
            rating("n3", "NAT", 3, scale=(1, 10)), rating("n4", "NAT", 4, scale=(1, 10))]
    flagged = apply_exclusions(read_ratings(ratings_csv(rows)))
    excluded = flagged.set_index("participant")["excluded_participant"].to_dict()
    assert excluded == {"p7": False, "p8": True, "n3": True, "n4": False}


def test_disagreeing_app_flags_are_reported():
    rows = [rating("p1", "BAD", 5, excluded_participant="false", discarded_early="false",
                   answered_before_end="false")]
    flagged = apply_exclusions(read_ratings(ratings_csv(rows)))
    notes = exclusion_notes(flagged)
    assert any("excluded_participant flag disagrees" in n for n in notes)


def test_custom_system_names_for_natural_and_attention_clips():
    rows = [rating("p1", "mocap", 1), rating("p2", "mocap", 4)]
    flagged = apply_exclusions(read_ratings(ratings_csv(rows)), ExclusionRules(natural_system="mocap"))
    assert flagged["excluded_participant"].tolist() == [True, False]
