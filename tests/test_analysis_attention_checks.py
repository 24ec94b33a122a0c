"""Comparing the attention-check system (``--compare-attention-checks``) compares it as a
system: its ratings exclude nobody, and the summary says which rules were applied."""

from __future__ import annotations

import pandas as pd

from analysis import build_report, validate_ratings
from analysis.cli import main
from analysis.reports.single_report import summary_text


def pairwise_with_a_bad_preference() -> pd.DataFrame:
    """Two participants; p2 prefers BAD over NAT on one page."""
    rows = []
    pages = [("p1", "NAT", "BAD", "left"), ("p1", "NAT", "A", "left"), ("p1", "A", "NAT", "right"),
             ("p2", "BAD", "NAT", "left"), ("p2", "NAT", "A", "left"), ("p2", "A", "NAT", "left")]
    for i, (participant, left, right, answer) in enumerate(pages):
        rows += [{"design": "pairwise", "participant": participant, "page": f"q{i}", "system": s,
                  "stimulus": f"{s}_{i}", "side": side, "answer": answer}
                 for side, s in (("left", left), ("right", right))]
    return pd.DataFrame(rows)


def single_with_a_high_bad_rating() -> pd.DataFrame:
    ratings = {"p1": {"NAT": [5, 4], "A": [3, 2], "BAD": [1]},
               "p2": {"NAT": [4, 5], "A": [2, 3], "BAD": [5]},
               "p3": {"NAT": [1, 4], "A": [3, 3], "BAD": [1]}}
    return pd.DataFrame([{"participant": p, "system": s, "stimulus": f"{s}_{i}", "value": v,
                          "scale_min": 1, "scale_max": 5}
                         for p, systems in ratings.items() for s, values in systems.items()
                         for i, v in enumerate(values)])


def test_comparing_bad_in_a_pairwise_table_excludes_nobody_for_preferring_it():
    ratings = validate_ratings(pairwise_with_a_bad_preference())
    checked = build_report(ratings)
    assert set(checked.flagged.loc[checked.flagged["excluded_participant"], "participant"]) == {"p2"}
    compared = build_report(ratings, compare_attention_checks=True)
    assert not compared.flagged["excluded_participant"].any()
    bad = compared.table("preference_pairs").query("system_a == 'BAD'").iloc[0]
    assert (bad["system_b"], bad["wins_a"], bad["wins_b"]) == ("NAT", 1, 1)
    summary = summary_text(compared)
    assert "no attention check was applied (BAD was compared as a system)" in summary
    assert "preferred a" not in summary


def test_comparing_bad_in_a_single_table_keeps_the_natural_rule_and_says_so():
    ratings = validate_ratings(single_with_a_high_bad_rating())
    compared = build_report(ratings, compare_attention_checks=True)
    excluded = compared.flagged.groupby("participant")["excluded_participant"].any()
    assert excluded.to_dict() == {"p1": False, "p2": False, "p3": True}  # p3 rated NAT 1
    assert "BAD" in set(compared.means["system"])
    summary = summary_text(compared)
    assert ("a participant was removed who rated any NAT clip below 2 (on a 1-5 scale; scaled "
            "linearly on others); BAD was compared as a system, not used as an attention check") in summary
    assert "BAD clip 4 or higher" not in summary
    checked = build_report(ratings)
    assert "rated any BAD clip 4 or higher or any NAT clip below 2" in summary_text(checked)


def test_the_command_line_option_compares_bad_without_excluding_on_it(tmp_path):
    path = tmp_path / "ratings.csv"
    pairwise_with_a_bad_preference().to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "out"), "--compare-attention-checks"]) == 0
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "Of 2 participants, 0 were removed" in summary
    assert "no attention check was applied (BAD was compared as a system)" in summary
