"""Side-by-side statistics against independent computations.

References: scipy.stats.wilcoxon (exact and asymptotic), statsmodels' multipletests
(Holm), scipy.stats.quantile_test (median interval), the t distribution (mean interval),
and a small example paired by hand.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats
from statsmodels.stats.multitest import multipletests

from analysis.stats.multiple_comparisons import holm_adjusted
from analysis.ratings.schema import validate_ratings
from analysis.stats.within_page import (median_and_mean, median_interval, page_differences,
                                   significance_matrix, signed_rank_pairs)
from analysis.stats.signed_rank import signed_rank_test
from analysis.ratings.simulate import simulate_side_by_side


@pytest.fixture(scope="module")
def pages() -> pd.DataFrame:
    table = simulate_side_by_side({"NAT": 78, "A": 60, "B": 57, "C": 45}, n_participants=30,
                                  inattentive_share=0.0, early_share=0.0, seed=11)
    return validate_ratings(table.astype(str))


def test_signed_rank_exact_branch_equals_scipy():
    rng = np.random.default_rng(0)
    for n in (6, 13, 29, 50):
        d = rng.normal(0.4, 1.0, n)  # continuous: no ties, so the exact branch
        ours, theirs = signed_rank_test(d), stats.wilcoxon(d, method="exact")
        assert ours.method == "exact"
        assert ours.statistic == theirs.statistic
        assert ours.p == pytest.approx(theirs.pvalue, rel=1e-12)


def test_signed_rank_with_ties_and_zeros_equals_scipy_normal_approximation():
    rng = np.random.default_rng(1)
    d = np.rint(rng.normal(3, 12, 140))  # slider differences: ties and some zeros
    assert (d == 0).any()
    ours = signed_rank_test(d)
    theirs = stats.wilcoxon(d, zero_method="wilcox", method="asymptotic", correction=False)
    assert ours.method == "normal" and ours.n_nonzero == int((d != 0).sum())
    assert ours.statistic == theirs.statistic
    assert ours.p == pytest.approx(theirs.pvalue, rel=1e-10)


def test_holm_equals_statsmodels_multipletests():
    p = np.array([0.01, 0.04, 0.03, 0.2, 0.001, 0.04, 0.8])
    np.testing.assert_allclose(holm_adjusted(p), multipletests(p, method="holm")[1], rtol=1e-14)
    with_gap = holm_adjusted([0.01, np.nan, 0.02])
    assert np.isnan(with_gap[1]) and with_gap[[0, 2]].tolist() == pytest.approx([0.02, 0.02])


def test_hand_paired_example():
    # two participants, two pages each; A - B per page: 10, -5, 20, 30 -> ranks of |d|
    # 2, 1, 3, 4; T+ = 9, T- = 1, so the statistic is 1; exact p = 2 * 2/16 = 0.25
    rows = [("p1", "c1", "A", 60), ("p1", "c1", "B", 50), ("p1", "c2", "A", 40), ("p1", "c2", "B", 45),
            ("p2", "c1", "A", 70), ("p2", "c1", "B", 50), ("p2", "c2", "A", 80), ("p2", "c2", "B", 50)]
    data = pd.DataFrame(rows, columns=["participant", "page", "system", "value"]).assign(
        task="t", control_class="c")
    pair = signed_rank_pairs(data).iloc[0]
    assert (pair["n_pages"], pair["statistic"], pair["higher"]) == (4, 1.0, "A")
    assert pair["p"] == pytest.approx(0.25)
    assert pair["median_diff"] == 15.0 and pair["mean_diff"] == 13.75


def test_pairs_use_only_pages_showing_both_systems(pages):
    subset = pages[~((pages["system"] == "C") & (pages["page"].isin(["c0", "c1", "c2"])))]
    diffs = page_differences(subset)
    a_c = diffs[(diffs["system_a"] == "A") & (diffs["system_b"] == "C")]
    wide = subset.pivot_table(index=["participant", "page"], columns="system", values="value")
    expected = (wide["A"] - wide["C"]).dropna()
    assert len(a_c) == len(expected) < len(wide)
    got = a_c.set_index(["participant", "page"])["difference"].sort_index()
    np.testing.assert_array_equal(got.to_numpy(), expected.sort_index().to_numpy())


def test_signed_rank_pairs_equal_scipy_on_pivoted_pages_with_holm_over_the_cell(pages):
    pairs = signed_rank_pairs(pages).set_index(["system_a", "system_b"])
    wide = pages.pivot_table(index=["participant", "page"], columns="system", values="value")
    raw = {}
    for a, b in pairs.index:
        raw[(a, b)] = stats.wilcoxon(wide[a], wide[b], method="asymptotic").pvalue
        assert pairs.loc[(a, b), "p"] == pytest.approx(raw[(a, b)], rel=1e-10)
    holm = multipletests(list(raw.values()), method="holm")[1]
    np.testing.assert_allclose(pairs.loc[list(raw), "p_holm"], holm, rtol=1e-12)
    assert pairs.loc[("A", "NAT"), "higher"] == "NAT" and pairs.loc[("A", "NAT"), "reject"]


def test_holm_runs_separately_per_control_class(pages):
    other = pages.assign(control_class="synthetic")
    other = other[other["system"].isin(["A", "B"])]
    pairs = signed_rank_pairs(pd.concat([pages, other]))
    synthetic = pairs[pairs["control_class"] == "synthetic"]
    assert len(synthetic) == 1  # one pair, so Holm leaves its p-value as it is
    assert synthetic["p_holm"].iloc[0] == synthetic["p"].iloc[0]


def test_median_interval_equals_scipy_quantile_test():
    rng = np.random.default_rng(2)
    for n in (6, 9, 20, 101, 400):
        x = np.rint(rng.normal(50, 20, n))
        ci = stats.quantile_test(x, q=np.median(x), p=0.5).confidence_interval(0.95)
        assert median_interval(x) == (pytest.approx(ci.low), pytest.approx(ci.high))
    assert np.isnan(median_interval([1, 2, 3, 4, 5])).all()  # n = 5 cannot reach 95 %


def test_median_and_mean_table(pages):
    table = median_and_mean(pages).set_index("system")
    values = pages.loc[pages["system"] == "B", "value"]
    half = stats.t.ppf(0.975, len(values) - 1) * values.std(ddof=1) / np.sqrt(len(values))
    assert table.loc["B", "median"] == values.median()
    assert table.loc["B", "ci_half"] == pytest.approx(half)
    assert table.loc["B", "median_ci_low"] <= table.loc["B", "median"] <= table.loc["B", "median_ci_high"]


def test_significance_matrix_is_antisymmetric_and_points_to_the_higher_system(pages):
    pairs = signed_rank_pairs(pages)
    matrix = significance_matrix(pairs, ["NAT", "A", "B", "C"])
    values = matrix.to_numpy()
    assert np.isnan(np.diag(values)).all()
    off = ~np.eye(4, dtype=bool)
    np.testing.assert_array_equal(values[off], -values.T[off])
    assert matrix.loc["NAT", "C"] == 1 and matrix.loc["C", "NAT"] == -1
    a_b = pairs[(pairs["system_a"] == "A") & (pairs["system_b"] == "B")].iloc[0]
    assert matrix.loc["A", "B"] == (0 if not a_b["reject"] else 1 if a_b["higher"] == "A" else -1)
