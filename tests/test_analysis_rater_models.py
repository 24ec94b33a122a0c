"""Rater agreement against Krippendorff's worked example and a direct computation, and
the rater-models command on single and side-by-side tables."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.raters.agreement import rater_agreement
from analysis.cli import main
from analysis.ratings.simulate import simulate_ratings, simulate_side_by_side

# Krippendorff (2011), "Computing Krippendorff's alpha-reliability", the example with
# missing values: four observers, twelve units, values 1-5
EXAMPLE = {"A": [1, 2, 3, 3, 2, 1, 4, 1, 2, None, None, None],
           "B": [1, 2, 3, 3, 2, 2, 4, 1, 2, 5, None, 3],
           "C": [None, 3, 3, 3, 2, 3, 4, 2, 2, 5, 1, None],
           "D": [1, 2, 3, 3, 2, 4, 4, 1, 2, 5, 1, None]}


def tidy(matrix: dict[str, list]) -> pd.DataFrame:
    return pd.DataFrame([{"participant": p, "stimulus": f"u{u}", "value": v, "task": "t", "control_class": "c"}
                         for p, values in matrix.items() for u, v in enumerate(values) if v is not None])


def test_alpha_reproduces_krippendorffs_worked_example():
    table, notes = rater_agreement(tidy(EXAMPLE))
    row = table.iloc[0]
    # the published values: interval 0.849, ordinal 0.815; unit 12 has one value and is not pairable
    assert (round(row["alpha_interval"], 3), round(row["alpha_ordinal"], 3)) == (0.849, 0.815)
    assert row["stimuli"] == 11 and notes == []


def direct_interval_alpha(table: pd.DataFrame) -> float:
    """1 - D_o / D_e with squared differences, from the pairable values unit by unit."""
    units = [g["value"].to_numpy(float) for _, g in table.groupby("stimulus") if len(g) >= 2]
    values = np.concatenate(units)
    n = len(values)
    observed = sum(((u[:, None] - u[None, :]) ** 2).sum() / (len(u) - 1) for u in units) / n
    expected = ((values[:, None] - values[None, :]) ** 2).sum() / (n * (n - 1))
    return 1 - observed / expected


def test_interval_alpha_equals_a_direct_computation_on_simulated_ratings():
    ratings = simulate_ratings({"NAT": 4.2, "A": 3.1}, 600, control_classes=("c",), stimuli_per_system=15, seed=3)
    table, _ = rater_agreement(ratings)
    assert table["alpha_interval"].iloc[0] == pytest.approx(direct_interval_alpha(ratings), abs=1e-10)


def test_a_cell_without_a_clip_rated_twice_is_noted():
    table, notes = rater_agreement(tidy({"A": [1, 2], "B": [None, None, 3]}))
    assert table.empty and notes == ["No rater agreement for t · c: no clip was rated by two "
                                     "participants with some spread in the ratings."]


def test_the_command_writes_the_three_models_for_a_likert_table(tmp_path):
    path = tmp_path / "ratings.csv"
    simulate_ratings({"NAT": 4.1, "A": 3.4, "B": 3.0}, 900, control_classes=("c",), seed=4).to_csv(path, index=False)
    out = tmp_path / "models"
    assert main(["rater-models", str(path), "--out", str(out)]) == 0
    for name in ("crossed_mixed_estimates", "crossed_mixed_contrasts", "crossed_mixed_variance",
                 "ordinal_mixed_thresholds", "ordinal_mixed_effects", "ordinal_mixed_random", "rater_agreement"):
        assert (out / "tables" / f"{name}.csv").is_file(), name
    contrasts = pd.read_csv(out / "tables" / "crossed_mixed_contrasts.csv")
    assert set(contrasts["reference"]) == {"NAT"} and set(contrasts["system"]) == {"A", "B"}
    summary = (out / "summary.md").read_text()
    assert "crossed random intercepts for participants and clips (REML)" in summary
    assert "cumulative link (logit) mixed model" in summary and "Krippendorff's alpha" in summary


def test_a_slider_table_gets_no_cumulative_link_model_and_says_why(tmp_path):
    path = tmp_path / "ratings.csv"
    simulate_side_by_side({"NAT": 78, "A": 62, "BAD": 10}, n_participants=12, seed=2).to_csv(path, index=False)
    assert main(["rater-models", str(path), "--out", str(tmp_path / "models"), "--reference", "A"]) == 0
    assert not (tmp_path / "models" / "tables" / "ordinal_mixed_effects.csv").exists()
    summary = (tmp_path / "models" / "summary.md").read_text()
    assert "its 0-100 scale has more than 11 points" in summary and "Against A" in summary


def test_the_command_refuses_a_pairwise_table_and_an_unknown_reference(tmp_path, capsys):
    pairwise = tmp_path / "pairwise.csv"
    pd.DataFrame({"design": "pairwise", "participant": "p", "page": "q", "system": ["A", "B"],
                  "stimulus": ["a", "b"], "side": ["left", "right"], "answer": "left"}).to_csv(pairwise, index=False)
    assert main(["rater-models", str(pairwise), "--out", str(tmp_path / "a")]) == 2
    single = tmp_path / "single.csv"
    simulate_ratings({"NAT": 4.1, "A": 3.4}, 200, seed=1).to_csv(single, index=False)
    assert main(["rater-models", str(single), "--out", str(tmp_path / "b"), "--reference", "Z"]) == 2
    err = capsys.readouterr().err
    assert "rater-models analyses single and side-by-side tables" in err
    assert "reference system 'Z' has no compared ratings" in err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_single_and_side_by_side_reports_include_the_rater_models(tmp_path):
    single = tmp_path / "single.csv"
    simulate_ratings({"NAT": 4.1, "A": 3.4}, 600, control_classes=("c",), seed=2).to_csv(single, index=False)
    assert main(["report", str(single), "--out", str(tmp_path / "a")]) == 0
    for name in ("crossed_mixed_contrasts", "ordinal_mixed_effects", "rater_agreement"):
        assert (tmp_path / "a" / "tables" / f"{name}.csv").is_file(), name
    assert "crossed random intercepts for participants and clips" in (tmp_path / "a" / "summary.md").read_text()
    sbs = tmp_path / "sbs.csv"
    simulate_side_by_side({"NAT": 78, "A": 62, "BAD": 10}, n_participants=12, seed=2).to_csv(sbs, index=False)
    assert main(["report", str(sbs), "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "tables" / "crossed_mixed_variance.csv").is_file()
    assert not (tmp_path / "b" / "tables" / "ordinal_mixed_effects.csv").exists()
