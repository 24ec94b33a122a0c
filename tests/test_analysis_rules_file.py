"""The exclusion rules as a file (the study app's rules.json): read back exactly, and a file
that is not rules refused with exit status 2 naming what is wrong, before anything is written."""

from __future__ import annotations

import pytest

from analysis.cli import main
from analysis.ratings.exclusions import ExclusionRules


def test_rules_written_as_json_read_back_the_same():
    rules = ExclusionRules(natural_system="mocap", attention_system="broken", bad_at_or_above=3.5,
                           natural_below=2.5, discard_early=False)
    assert ExclusionRules.from_json(rules.to_json()) == rules


@pytest.mark.parametrize("text, message", [
    ("not json", "is not JSON"),
    ("[4.0]", "must be a JSON object"),
    ('{"threshold": 4}', "unknown field(s) threshold"),
    ('{"bad_at_or_above": "4"}', "bad_at_or_above must be a float"),
    ('{"discard_early": 1}', "discard_early must be a bool"),
    ('{"natural_below": NaN}', "must be a finite number"),
])
def test_a_rules_file_that_is_not_rules_exits_2_naming_the_problem(text, message, tmp_path, capsys):
    rules = tmp_path / "rules.json"
    rules.write_text(text)
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "ratings.csv"), "--rules", str(rules), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert message in error and "rules.json" in error and not out.exists()


def test_rules_given_both_as_a_file_and_as_options_exit_2(tmp_path, capsys):
    rules = tmp_path / "rules.json"
    rules.write_text(ExclusionRules().to_json())
    assert main(["report", str(tmp_path / "ratings.csv"), "--rules", str(rules), "--bad-threshold", "3",
                 "--out", str(tmp_path / "report")]) == 2
    assert "not both" in capsys.readouterr().err
