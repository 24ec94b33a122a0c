"""ANOVA, Tukey HSD, confidence intervals and the mixed model against references.

References: scipy.stats.f_oneway, scipy.stats.tukey_hsd, statsmodels' pairwise_tukeyhsd
and MixedLM, the t distribution, and a small example worked by hand.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.errors import AnalysisInputError
from analysis.raters.mixed import mixed_model_means
from analysis.stats.anova import anova, pvalue_matrix, system_means, tukey_hsd
from analysis.stats.studentized_range import studentized_range_ppf, studentized_range_sf


def tidy(groups: dict[str, list[float]], task="t", control_class="c") -> pd.DataFrame:
    return pd.DataFrame([{"task": task, "control_class": control_class, "system": s, "value": v}
                         for s, values in groups.items() for v in values])


@pytest.fixture
def uneven_groups() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    return {name: np.clip(np.rint(rng.normal(mu, 1.0, n)), 1, 5)
            for name, mu, n in (("A", 3.0, 40), ("B", 3.4, 55), ("C", 2.6, 31), ("D", 3.1, 47))}


def test_hand_worked_example():
    # A = 1,2,3; B = 3,4,5; C = 5,6,7 on a 1-7 scale: means 2, 4, 6, grand mean 4.
    # SS_between = 3 (4 + 0 + 4) = 24 on 2 df; SS_within = 2 + 2 + 2 = 6 on 6 df;
    # F = (24 / 2) / (6 / 6) = 12; for F(2, 6), P(F > f) = (1 + 2 f / 6)^-3 = 5^-3 = 0.008.
    data = tidy({"A": [1, 2, 3], "B": [3, 4, 5], "C": [5, 6, 7]})
    result = anova(data).iloc[0]
    assert (result["df_between"], result["df_within"]) == (2, 6)
    assert result["F"] == pytest.approx(12.0)
    assert result["p"] == pytest.approx(0.008)
    assert result["eta_squared"] == pytest.approx(0.8)
    # Tukey: MSE = 1, se = sqrt(1/2 (1/3 + 1/3)) = 0.5774; q(A,B) = 2 / se = 3.464 and
    # q(A,C) = 6.928. The tabled 5 % critical value for k = 3, df = 6 is 4.34, so only
    # A-C differs significantly.
    pairs = tukey_hsd(data).set_index(["system_a", "system_b"])
    assert pairs.loc[("A", "B"), "q"] == pytest.approx(2 / np.sqrt(1 / 3))
    assert pairs["reject"].to_dict() == {("A", "B"): False, ("A", "C"): True, ("B", "C"): False}
    assert studentized_range_ppf(0.95, 3, 6) == pytest.approx(4.34, abs=0.005)
    # CI: mean 2, sd 1, n 3: half-width t(0.975, 2) / sqrt(3) = 4.303 / 1.732 = 2.484
    means = system_means(data).set_index("system")
    assert means.loc["A", "ci_half"] == pytest.approx(2.484, abs=5e-4)


def test_anova_equals_scipy_f_oneway(uneven_groups):
    result = anova(tidy(uneven_groups)).iloc[0]
    reference = stats.f_oneway(*uneven_groups.values())
    assert result["F"] == pytest.approx(reference.statistic, rel=1e-12)
    assert result["p"] == pytest.approx(reference.pvalue, rel=1e-9)


def test_anova_runs_per_task_and_control_class(uneven_groups):
    data = pd.concat([tidy(uneven_groups, "loco", "held-out"), tidy(uneven_groups, "loco", "synthetic"),
                      tidy({"A": [1, 2, 3], "B": [3, 4, 5]}, "gesture", "held-out")])
    result = anova(data)
    assert list(zip(result["task"], result["control_class"])) == [
        ("gesture", "held-out"), ("loco", "held-out"), ("loco", "synthetic")]


def test_tukey_equals_scipy_and_statsmodels(uneven_groups):
    from statsmodels.stats.multicomp import pairwise_tukeyhsd

    pairs = tukey_hsd(tidy(uneven_groups))
    names = sorted(uneven_groups)
    sp = stats.tukey_hsd(*(uneven_groups[n] for n in names))
    ci = sp.confidence_interval(0.95)
    index = {n: i for i, n in enumerate(names)}
    for row in pairs.itertuples():
        i, j = index[row.system_a], index[row.system_b]
        # scipy reports mean_i - mean_j; we (like statsmodels) mean_b - mean_a
        assert row.diff == pytest.approx(-sp.statistic[i, j], rel=1e-12)
        assert row.p_adj == pytest.approx(sp.pvalue[i, j], abs=1e-9)
        assert (row.ci_low, row.ci_high) == pytest.approx((-ci.high[i, j], -ci.low[i, j]), abs=1e-8)
    values = np.concatenate([uneven_groups[n] for n in names])
    labels = np.repeat(names, [len(uneven_groups[n]) for n in names])
    sm = pairwise_tukeyhsd(values, labels, alpha=0.05)
    assert pairs["p_adj"].to_numpy() == pytest.approx(sm.pvalues, abs=1e-9)
    assert pairs["diff"].to_numpy() == pytest.approx(sm.meandiffs, rel=1e-12)
    assert pairs["reject"].tolist() == list(sm.reject)
    assert pairs[["ci_low", "ci_high"]].to_numpy() == pytest.approx(sm.confint, abs=1e-8)


@pytest.mark.parametrize("k", [2, 3, 10])
@pytest.mark.parametrize("df", [1, 4, 30, 1000, 50_000, np.inf])
def test_studentized_range_matches_scipy(k, df):
    q = np.linspace(0.05, 9.0, 12)
    assert studentized_range_sf(q, k, df) == pytest.approx(stats.studentized_range.sf(q, k, df), abs=1e-9)


def test_confidence_intervals_follow_the_t_distribution(uneven_groups):
    means = system_means(tidy(uneven_groups), confidence=0.95).set_index("system")
    for name, values in uneven_groups.items():
        low, high = stats.t.interval(0.95, len(values) - 1, loc=values.mean(), scale=stats.sem(values))
        ours = (means.loc[name, "ci_low"], means.loc[name, "ci_high"])
        assert ours == pytest.approx((low, high), rel=1e-12)
        assert means.loc[name, "n"] == len(values)


def test_a_system_with_one_rating_is_a_clear_error():
    with pytest.raises(AnalysisInputError, match="fewer than two ratings"):
        system_means(tidy({"A": [1, 2, 3], "B": [4]}))


def test_pvalue_matrix_is_symmetric_with_an_empty_diagonal(uneven_groups):
    matrix = pvalue_matrix(tukey_hsd(tidy(uneven_groups)))
    assert list(matrix.index) == ["A", "B", "C", "D"]
    assert np.allclose(matrix.to_numpy(), matrix.to_numpy().T, equal_nan=True)
    assert matrix.isna().to_numpy().sum() == 4


def test_mixed_model_equals_statsmodels_mixedlm():
    import statsmodels.formula.api as smf

    rng = np.random.default_rng(7)
    n, participants = 1500, 40
    who = rng.integers(0, participants, n)
    system = rng.integers(0, 4, n)
    value = np.clip(np.rint(3 + 0.3 * system + rng.normal(0, 0.6, participants)[who]
                            + rng.normal(0, 0.9, n)), 1, 5)
    data = pd.DataFrame({"task": "t", "control_class": "c", "system": [f"S{s}" for s in system],
                         "participant": [f"p{w}" for w in who], "value": value})
    ours = mixed_model_means(data).set_index("system")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = smf.mixedlm("value ~ 0 + C(system)", data, groups=data["participant"]).fit(reml=True)
    assert ours["estimate"].to_numpy() == pytest.approx(fit.fe_params.to_numpy(), abs=1e-5)
    assert ours["se"].to_numpy() == pytest.approx(fit.bse_fe.to_numpy(), rel=1e-4)
    assert ours["ci_low"].to_numpy() == pytest.approx(fit.conf_int().iloc[:4, 0].to_numpy(), abs=1e-4)
    assert ours["residual_var"].iloc[0] == pytest.approx(fit.scale, rel=1e-4)
    assert ours["participant_var"].iloc[0] == pytest.approx(float(fit.cov_re.iloc[0, 0]), rel=1e-3)
    assert not ours["at_boundary"].any()


def test_mixed_model_reports_a_zero_participant_variance_at_the_boundary():
    # each participant's ratings sum to the same total, so participants do not differ
    # at all on average: the REML estimate of their variance is zero
    rng = np.random.default_rng(1)
    first = rng.integers(1, 6, 100)
    data = pd.DataFrame({"task": "t", "control_class": "c",
                         "system": np.tile(["A", "B"], 100),
                         "participant": np.repeat([f"p{i}" for i in range(100)], 2),
                         "value": np.column_stack([first, 6 - first]).ravel()})
    result = mixed_model_means(data)
    assert result["at_boundary"].all()
    plain = system_means(data).set_index("system")["mean"]
    assert result.set_index("system")["estimate"].to_numpy() == pytest.approx(plain.to_numpy())
