"""Side-by-side and pairwise reports end to end: the same command picks the analysis from
the design column and writes its tables, figures and paragraph."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis import build_report, validate_ratings
from analysis.cli import main
from analysis.motion.motion_io import save_clips
from analysis.stats.power import SEQUENTIAL_LOOKS_NOTE
from analysis.ratings.simulate import simulate_pairwise, simulate_ratings, simulate_side_by_side

FORMATS = ("csv", "md", "tex", "json")


@pytest.fixture(scope="module")
def side_by_side() -> pd.DataFrame:
    return simulate_side_by_side({"NAT": 78, "A": 62, "B": 58, "C": 40, "BAD": 12},
                                 n_participants=24, seed=6)


@pytest.fixture(scope="module")
def pairwise() -> pd.DataFrame:
    return simulate_pairwise({"NAT": 1.2, "A": 0.4, "B": 0.2, "BAD": -6.0}, n_participants=40,
                             pairs=[("NAT", "A"), ("NAT", "B"), ("A", "B"), ("NAT", "BAD")], seed=6)


def run_report(table: pd.DataFrame, tmp_path, *options) -> tuple[int, str]:
    path = tmp_path / "ratings.csv"
    table.to_csv(path, index=False)
    return main(["report", str(path), "--out", str(tmp_path / "out"), *options]), tmp_path / "out"


def test_side_by_side_report_writes_its_tables_figures_and_paragraph(side_by_side, tmp_path):
    status, out = run_report(side_by_side, tmp_path)
    assert status == 0
    for name in ("system_medians_means", "wilcoxon_pairs", "mixed_model_means",
                 "power_more_ratings", "exclusions"):
        assert all((out / "tables" / f"{name}.{fmt}").is_file() for fmt in FORMATS), name
    for name in ("significance_matrix", "median_mean_ci"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 0
    assert not (out / "tables" / "anova.csv").exists()  # pages are paired: no between-ratings ANOVA
    pairs = json.loads((out / "tables" / "wilcoxon_pairs.json").read_text())
    report = build_report(validate_ratings(side_by_side.astype(str)))
    assert [p["p_holm"] for p in pairs] == pytest.approx(report.table("wilcoxon_pairs")["p_holm"].tolist())
    assert {p["system_a"] for p in pairs} | {p["system_b"] for p in pairs} == {"NAT", "A", "B", "C"}
    summary = (out / "summary.md").read_text()
    assert "Wilcoxon signed-rank tests on the per-page rating differences" in summary
    assert "Holm-Bonferroni corrected over the 6 pairs" in summary
    assert "rated any BAD clip 75 or higher or any NAT clip below 25 (on the 0-100 scale)" in summary
    assert SEQUENTIAL_LOOKS_NOTE in summary


def test_side_by_side_drops_the_attention_clip_but_keeps_the_rest_of_its_page(side_by_side):
    report = build_report(validate_ratings(side_by_side.astype(str)))
    flagged = report.flagged
    kept_pages = flagged[flagged["kept"]].groupby(["participant", "page"]).ngroups
    means = report.table("system_medians_means").set_index("system")
    assert "BAD" not in means.index
    assert means.loc["NAT", "n"] == ((flagged["system"] == "NAT") & flagged["kept"]).sum()
    assert means.loc["NAT", "n"] >= kept_pages - 5  # early answers drop single clips only


def test_pairwise_report_writes_shares_scale_bias_and_power(pairwise, tmp_path):
    status, out = run_report(pairwise, tmp_path)
    assert status == 0
    for name in ("preference_pairs", "bradley_terry", "side_bias", "power_more_ratings"):
        assert all((out / "tables" / f"{name}.{fmt}").is_file() for fmt in FORMATS), name
    for name in ("preferences", "bradley_terry"):
        assert (out / "figures" / f"{name}.svg").stat().st_size > 0
    summary = (out / "summary.md").read_text()
    assert ("answered 'no preference' and left out of the preference shares, the exact two-sided "
            "binomial (sign) tests and the Bradley-Terry scale") in summary
    assert "NAT over A" in summary and SEQUENTIAL_LOOKS_NOTE in summary


def test_pairwise_attention_pages_leave_the_comparisons_unless_asked(pairwise):
    ratings = validate_ratings(pairwise.astype(str))
    report = build_report(ratings)
    pairs = report.table("preference_pairs")
    assert "BAD" not in set(pairs["system_a"]) | set(pairs["system_b"])
    assert len(pairs) == 3
    with_checks = build_report(ratings, compare_attention_checks=True).table("preference_pairs")
    bad = with_checks[with_checks["system_a"] == "BAD"].iloc[0]
    assert bad["system_b"] == "NAT" and bad["wins_b"] > 0 and bad["wins_a"] == 0


def test_motion_with_a_side_by_side_table_is_refused_without_a_traceback(side_by_side, tmp_path, capsys):
    positions = np.zeros((30, 2, 3))
    positions[:, 1, 1] = 50.0
    (tmp_path / "motion").mkdir()
    save_clips(tmp_path / "motion" / "NAT.npz", positions, 30.0, ["hips", "head"], [-1, 0])
    status, out = run_report(side_by_side, tmp_path, "--motion", str(tmp_path / "motion"))
    captured = capsys.readouterr()
    assert status == 2 and not out.exists(), captured
    assert "objective metrics (--motion) are reported with single-design ratings" in captured.err


def test_single_report_gains_the_power_table_and_paragraph(tmp_path):
    ratings = simulate_ratings({"NAT": 4.2, "A": 3.5, "B": 3.4}, 1500, seed=2)
    status, out = run_report(ratings, tmp_path)
    assert status == 0
    power = pd.read_csv(out / "tables" / "power_more_ratings.csv")
    assert set(power["unit"]) == {"ratings per system"} and len(power) == 6  # 3 pairs x 2 classes
    assert "**Power.**" in (out / "summary.md").read_text()


def test_the_preference_plot_draws_a_pair_whose_decided_pages_all_went_one_way():
    from analysis.reports.design_plots import preference_plot
    from analysis.stats.preferences import preference_pairs

    # 5 pages: 1 preferring A, 4 without preference (1 - 4/5 is a hair under 1/5 in floating point).
    rows = [{"task": "all", "control_class": "held-out", "participant": f"p{page}", "page": page, "system": system,
             "side": side, "answer": "left" if page == 0 else "none"}
            for page in range(5) for system, side in (("A", "left"), ("B", "right"))]
    pairs = preference_pairs(pd.DataFrame(rows))
    assert (pairs["wins_a"].item(), pairs["no_preference"].item()) == (1, 4) and preference_plot(pairs) is not None

