"""The Wilcoxon signed-rank test's continuity correction (R's default, scipy's option):
the same p-values as scipy with and without it, and every side-by-side and
appropriateness report says which was used."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from analysis import build_report, validate_ratings
from analysis.cli import main
from analysis.stats.signed_rank import signed_rank_test
from analysis.stats.matching import appropriateness_pages, score_pairs
from analysis.ratings.simulate import simulate_appropriateness, simulate_side_by_side


@pytest.mark.parametrize("correction", [False, True])
def test_the_normal_approximation_equals_scipy_with_and_without_the_correction(correction):
    rng = np.random.default_rng(2)
    for n in (12, 40, 80):
        d = np.round(rng.normal(0.4, 1.0, n), 1)  # tied magnitudes: the normal branch
        ours = signed_rank_test(d, continuity=correction)
        reference = stats.wilcoxon(d, method="asymptotic", correction=correction, zero_method="wilcox")
        assert ours.p == pytest.approx(reference.pvalue, rel=1e-12)
        assert ours.method == ("normal, continuity-corrected" if correction else "normal")


def test_the_correction_leaves_the_exact_test_alone():
    d = np.array([1.5, -0.2, 2.3, 0.7, 1.1, -0.9, 3.4, 0.4])
    assert signed_rank_test(d, continuity=True) == signed_rank_test(d)


def test_every_side_by_side_report_states_whether_it_corrected(tmp_path):
    table = simulate_side_by_side({"NAT": 78, "A": 62, "B": 58}, n_participants=24, seed=6)
    path = tmp_path / "ratings.csv"
    table.to_csv(path, index=False)
    for options, words in (([], "without continuity correction"),
                           (["--continuity-correction"], "with continuity correction")):
        out = tmp_path / f"out{len(options)}"
        assert main(["report", str(path), "--out", str(out), *options]) == 0
        assert f"else the normal approximation {words})" in (out / "summary.md").read_text()
    corrected = build_report(validate_ratings(table.astype(str)), continuity_correction=True)
    plain = build_report(validate_ratings(table.astype(str)))
    normal = corrected.table("wilcoxon_pairs")["method"] != "exact"
    assert normal.any() and (corrected.table("wilcoxon_pairs")["p"][normal]
                             > plain.table("wilcoxon_pairs")["p"][normal]).all()


def test_the_appropriateness_score_tests_equal_scipy_with_and_without_the_correction_and_say_which(tmp_path):
    table = validate_ratings(simulate_appropriateness({"NAT": 0.85, "A": 0.7, "B": 0.6}, n_participants=60,
                                                      seed=4).astype(str))
    path = tmp_path / "ratings.csv"
    table.to_csv(path, index=False)
    pages = appropriateness_pages(table)
    for correction, words in ((False, "without continuity correction"), (True, "with continuity correction")):
        pairs = score_pairs(table, continuity=correction)
        for pair in pairs.itertuples(index=False):
            means = pages[pages["task"] == pair.task].pivot_table(index="participant", columns="system",
                                                                  values="score", aggfunc="mean")
            d = (means[pair.system_a] - means[pair.system_b]).dropna().to_numpy()
            reference = stats.wilcoxon(d, method="asymptotic", correction=correction, zero_method="wilcox")
            assert pair.method == ("normal, continuity-corrected" if correction else "normal")
            assert pair.p == pytest.approx(reference.pvalue, rel=1e-12)
        out = tmp_path / f"out{int(correction)}"
        assert main(["report", str(path), "--out", str(out), *(["--continuity-correction"] * correction)]) == 0
        assert f"else the normal approximation {words})" in (out / "summary.md").read_text()
