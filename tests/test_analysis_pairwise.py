"""Pairwise preference statistics against independent computations.

References: scipy.stats.binomtest (sign test), statsmodels' proportion_confint (Wilson)
and multipletests (Holm), and for the Bradley-Terry scale a logistic regression of the
same comparisons fitted by statsmodels' GLM (a second fitting method).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from scipy import stats
from statsmodels.stats.multitest import multipletests
from statsmodels.stats.proportion import proportion_confint

from analysis.rankings.bradley_terry import bradley_terry_scale, fit_bradley_terry, win_matrix
from analysis.errors import AnalysisInputError
from analysis.stats.preferences import (preference_pages, preference_pairs, side_bias, sign_test_p,
                               wilson_interval)
from analysis.ratings.schema import validate_ratings
from analysis.ratings.simulate import simulate_pairwise

STRENGTHS = {"NAT": 1.0, "A": 0.4, "B": 0.1, "C": -0.5}


@pytest.fixture(scope="module")
def preferences() -> pd.DataFrame:
    table = simulate_pairwise(STRENGTHS, n_participants=150, pages_per_participant=24,
                              no_preference_share=0.15, inattentive_share=0.0, seed=4)
    return validate_ratings(table.astype(str))


def test_sign_test_equals_scipy_binomtest():
    for k, n in [(0, 1), (3, 10), (5, 10), (0, 7), (20, 20), (55, 120), (480, 1000)]:
        assert sign_test_p(k, n) == pytest.approx(stats.binomtest(k, n, 0.5).pvalue, rel=1e-12)
    assert np.isnan(sign_test_p(0, 0))


def test_wilson_interval_equals_statsmodels():
    for k, n in [(0, 7), (3, 10), (20, 20), (55, 120)]:
        low, high = wilson_interval(k, n)
        assert (float(low), float(high)) == pytest.approx(proportion_confint(k, n, method="wilson"), abs=1e-12)


def test_counts_shares_and_no_preference_by_hand():
    rows = []
    answers = ["left", "left", "right", "none", "left"]  # A left on pages 0-2, B left on 3-4
    for i, answer in enumerate(answers):
        left, right = ("A", "B") if i < 3 else ("B", "A")
        rows += [{"task": "t", "control_class": "c", "participant": "p", "page": f"q{i}",
                  "system": s, "side": side, "answer": answer}
                 for side, s in (("left", left), ("right", right))]
    pair = preference_pairs(pd.DataFrame(rows)).iloc[0]
    # A won pages 0 and 1, B won page 2 (right) and page 4 (left); page 3: no preference
    assert (pair["wins_a"], pair["wins_b"], pair["no_preference"], pair["n_pages"]) == (2, 2, 1, 5)
    assert pair["share_a"] == 0.5 and pair["no_preference_share"] == 0.2
    assert pair["p"] == 1.0 and pair["preferred"] == ""


def test_preference_pairs_equal_scipy_and_statsmodels_per_pair(preferences):
    pairs = preference_pairs(preferences)
    assert len(pairs) == 6
    for row in pairs.itertuples():
        decided = row.wins_a + row.wins_b
        assert row.p == pytest.approx(stats.binomtest(row.wins_a, decided).pvalue, rel=1e-12)
        low, high = proportion_confint(row.wins_a, decided, method="wilson")
        assert (row.share_ci_low, row.share_ci_high) == (pytest.approx(low), pytest.approx(high))
    np.testing.assert_allclose(pairs["p_holm"], multipletests(pairs["p"], method="holm")[1], rtol=1e-12)
    nat_c = pairs[(pairs["system_a"] == "C") & (pairs["system_b"] == "NAT")].iloc[0]
    assert nat_c["preferred"] == "NAT" and nat_c["reject"]


def test_no_preference_pages_are_counted_but_left_out_of_the_test(preferences):
    pairs = preference_pairs(preferences)
    pages = preference_pages(preferences)
    assert pairs["n_pages"].sum() == len(pages)
    assert pairs["no_preference"].sum() == (pages["answer"] == "none").sum() > 0
    assert (pairs["wins_a"] + pairs["wins_b"] + pairs["no_preference"] == pairs["n_pages"]).all()


def test_side_bias_counts_left_answers(preferences):
    bias = side_bias(preferences).iloc[0]
    pages = preference_pages(preferences)
    decided = pages[pages["answer"] != "none"]
    assert bias["n_decided"] == len(decided) and bias["left"] == (decided["answer"] == "left").sum()
    assert bias["p"] == pytest.approx(stats.binomtest(bias["left"], bias["n_decided"]).pvalue)
    assert bias["p"] > 0.01  # the simulated raters pick sides without bias


def _glm_bradley_terry(systems: list[str], wins: np.ndarray):
    """Logistic regression: logit P(i beats j) = b_i - b_j, the first system fixed at 0."""
    k = len(systems)
    design, outcome = [], []
    for i in range(k):
        for j in range(i + 1, k):
            if wins[i, j] + wins[j, i]:
                x = np.zeros(k)
                x[i], x[j] = 1.0, -1.0
                design.append(x[1:])
                outcome.append([wins[i, j], wins[j, i]])
    fit = sm.GLM(np.array(outcome), np.array(design), family=sm.families.Binomial()).fit(tol=1e-12)
    centre = np.eye(k) - 1.0 / k
    covariance = np.zeros((k, k))
    covariance[1:, 1:] = fit.cov_params()
    return centre @ np.r_[0.0, fit.params], np.sqrt(np.diag(centre @ covariance @ centre.T))


def test_bradley_terry_mm_equals_a_logistic_regression_fit(preferences):
    systems, wins = win_matrix(preference_pages(preferences))
    strength, covariance, iterations = fit_bradley_terry(wins)
    glm_strength, glm_se = _glm_bradley_terry(systems, wins)
    assert iterations > 1
    np.testing.assert_allclose(strength, glm_strength, atol=1e-7)
    np.testing.assert_allclose(np.sqrt(np.diag(covariance)), glm_se, rtol=1e-5)
    assert strength.sum() == pytest.approx(0.0, abs=1e-12)


def test_bradley_terry_recovers_the_simulated_strengths(preferences):
    scale, notes = bradley_terry_scale(preference_pages(preferences))
    assert notes == []
    truth = pd.Series(STRENGTHS) - np.mean(list(STRENGTHS.values()))
    scale = scale.set_index("system")
    inside = (scale["ci_low"] <= truth[scale.index]) & (truth[scale.index] <= scale["ci_high"])
    assert inside.sum() >= 3  # 95 % intervals: at most one of four may miss by chance
    assert list(scale["strength"].sort_values(ascending=False).index) == ["NAT", "A", "B", "C"]


def test_bradley_terry_with_a_system_that_never_lost_is_noted_not_fitted():
    rows = []
    for i, (left, right, answer) in enumerate([("NAT", "A", "left"), ("A", "NAT", "right"),
                                              ("A", "B", "left"), ("B", "A", "left")]):
        rows += [{"task": "t", "control_class": "c", "participant": "p", "page": f"q{i}",
                  "system": s, "side": side, "answer": answer}
                 for side, s in (("left", left), ("right", right))]
    scale, notes = bradley_terry_scale(preference_pages(pd.DataFrame(rows)))
    assert scale.empty
    assert notes == ["No Bradley-Terry scale for t · c: 1 system(s) never lost and 0 never won a "
                     "comparison, so their strengths are unbounded."]
    with pytest.raises(AnalysisInputError, match="never lost"):
        fit_bradley_terry(np.array([[0.0, 2.0], [0.0, 0.0]]))
