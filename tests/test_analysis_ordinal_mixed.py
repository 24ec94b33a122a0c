"""The cumulative link mixed model against independent computations: statsmodels'
OrderedModel without random effects, the Laplace approximation computed with dense
matrices and scipy, the exact marginal likelihood integrated numerically with one random
factor, finite differences of the approximation for its gradient, and recovery of
simulated effects."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import optimize, special
from statsmodels.miscmodels.ordinal_model import OrderedModel

from analysis.raters.crossed_design import crossed_layout
from analysis.raters.ordinal_mixed import _Data, _gradient, _laplace, fit_ordinal, ordinal_mixed_model

EFFECTS = {"NAT": 0.0, "A": -0.8, "B": -1.3}
THRESHOLDS = np.array([-2.5, -1.0, 0.5, 2.0])


def likert(participants: int = 20, clips: int = 8, per_system: int = 6, participant_sd: float = 0.8,
           stimulus_sd: float = 0.5, seed: int = 2) -> pd.DataFrame:
    """1-5 ratings from the model: a latent logistic rating cut at THRESHOLDS."""
    rng = np.random.default_rng(seed)
    u = rng.normal(0, participant_sd, participants)
    v = rng.normal(0, stimulus_sd, (len(EFFECTS), clips))
    rows = []
    for p in range(participants):
        for s, (system, effect) in enumerate(EFFECTS.items()):
            for c in rng.choice(clips, per_system, replace=False):
                latent = effect + u[p] + v[s, c] + rng.logistic()
                rows.append((f"p{p}", system, f"{system}_{c}", 1 + int(np.searchsorted(THRESHOLDS, latent))))
    return pd.DataFrame(rows, columns=["participant", "system", "stimulus", "value"]).assign(
        task="t", control_class="c")


def test_without_random_effects_the_fit_equals_statsmodels_ordered_model():
    table = likert(seed=4)
    layout = crossed_layout(table, "NAT")
    fit = fit_ordinal(table["value"].to_numpy(), layout, random=())
    exog = pd.get_dummies(table["system"])[["A", "B"]].astype(float)
    reference = OrderedModel(table["value"].to_numpy(), exog, distr="logit").fit(
        method="newton", disp=False, maxiter=200)
    thresholds = reference.model.transform_threshold_params(reference.params)[1:-1]
    np.testing.assert_allclose(fit.thresholds, thresholds, atol=1e-6)
    np.testing.assert_allclose(fit.effects[1:], reference.params[["A", "B"]], atol=1e-6)
    np.testing.assert_allclose(np.sqrt(np.diag(fit.covariance))[4:], reference.bse[["A", "B"]], rtol=1e-3)
    assert (fit.participant_sd, fit.stimulus_sd) == (0.0, 0.0)


def dense_laplace(theta: np.ndarray, table: pd.DataFrame) -> float:
    """The Laplace approximation written out: g(w) = sum log P(y | eta) - |w|^2 / 2 with
    P from the logistic cdf, its mode by scipy, its Hessian by second differences."""
    alpha, beta, (s_p, s_s) = theta[:4], np.r_[0.0, theta[4:6]], theta[6:]
    system = table["system"].map({s: i for i, s in enumerate(EFFECTS)}).to_numpy()
    z_p = pd.get_dummies(table["participant"]).to_numpy(float)
    z_s = pd.get_dummies(table["stimulus"]).to_numpy(float)
    z = np.hstack([s_p * z_p, s_s * z_s])
    cuts = np.r_[-np.inf, alpha, np.inf]
    y = table["value"].to_numpy()

    def g(w):
        eta = beta[system] + z @ w
        return np.log(special.expit(cuts[y] - eta) - special.expit(cuts[y - 1] - eta)).sum() - 0.5 * w @ w

    mode = optimize.minimize(lambda w: -g(w), np.zeros(z.shape[1]), method="BFGS", options={"gtol": 1e-10}).x
    q, h = z.shape[1], 1e-4
    hessian = np.zeros((q, q))
    for i in range(q):
        for j in range(i, q):
            e_i, e_j = np.eye(q)[i] * h, np.eye(q)[j] * h
            hessian[i, j] = hessian[j, i] = -(g(mode + e_i + e_j) - g(mode + e_i - e_j)
                                              - g(mode - e_i + e_j) + g(mode - e_i - e_j)) / (4 * h * h)
    return g(mode) - 0.5 * np.linalg.slogdet(hessian)[1]


def small_problem():
    table = likert(participants=6, clips=4, per_system=3, seed=9)
    layout = crossed_layout(table, "NAT")
    category = table["value"].to_numpy() - 1
    assert set(category) == set(range(5))
    return table, _Data(layout, category, 5, (True, True))


def test_the_laplace_approximation_equals_a_dense_computation_with_scipy():
    table, data = small_problem()
    theta = np.array([-2.2, -0.9, 0.6, 1.8, -0.6, -1.1, 0.9, 0.6])
    assert _laplace(theta, data).value == pytest.approx(dense_laplace(theta, table), abs=1e-5)


def test_the_exact_gradient_equals_finite_differences_of_the_approximation():
    _, data = small_problem()
    theta = np.array([-2.2, -0.9, 0.6, 1.8, -0.6, -1.1, 0.9, 0.6])
    exact = _gradient(theta, data, _laplace(theta, data))
    steps = np.eye(len(theta)) * 1e-6
    numeric = [(_laplace(theta + e, data).value - _laplace(theta - e, data).value) / 2e-6 for e in steps]
    np.testing.assert_allclose(exact, numeric, rtol=1e-6, atol=1e-6)


def exact_participant_likelihood(theta: np.ndarray, table: pd.DataFrame, nodes: int = 40) -> float:
    """-log-likelihood with one random factor (participants), each participant's integral
    over u ~ N(0, 1) by Gauss-Hermite quadrature."""
    alpha = np.r_[theta[0], theta[0] + np.cumsum(np.exp(theta[1:4]))]
    beta, s_p = np.r_[0.0, theta[4:6]], np.exp(theta[6])
    x, weights = np.polynomial.hermite_e.hermegauss(nodes)
    cuts = np.r_[-np.inf, alpha, np.inf]
    total = 0.0
    for _, frame in table.groupby("participant"):
        fixed = beta[frame["system"].map({s: i for i, s in enumerate(EFFECTS)}).to_numpy()]
        y = frame["value"].to_numpy()
        eta = fixed[:, None] + s_p * x[None, :]
        log_p = np.log(special.expit(cuts[y][:, None] - eta) - special.expit(cuts[y - 1][:, None] - eta)).sum(axis=0)
        total += np.log(weights @ np.exp(log_p) / np.sqrt(2 * np.pi))
    return -total


def test_with_one_random_factor_the_estimates_are_close_to_the_exact_marginal_likelihood():
    table = likert(participants=15, clips=14, per_system=14, stimulus_sd=0.0, seed=9)
    layout = crossed_layout(table, "NAT")
    fit = fit_ordinal(table["value"].to_numpy(), layout, random=("participant",))
    start = np.r_[-2.5, np.log([1.5, 1.5, 1.5]), 0.0, 0.0, np.log(0.7)]
    exact = optimize.minimize(exact_participant_likelihood, start, args=(table,), method="BFGS").x
    alpha = np.r_[exact[0], exact[0] + np.cumsum(np.exp(exact[1:4]))]
    # 42 ratings per participant: the Laplace approximation is close, not exact
    np.testing.assert_allclose(fit.thresholds, alpha, atol=0.03)
    np.testing.assert_allclose(fit.effects[1:], exact[4:6], atol=0.01)
    assert fit.participant_sd == pytest.approx(np.exp(exact[6]), rel=0.03)
    assert fit.stimulus_sd == 0.0


def test_simulated_effects_and_spreads_are_recovered_and_tabled():
    table = likert(participants=60, clips=20, per_system=10, seed=11)
    tables = ordinal_mixed_model(table, reference="NAT")
    effects = tables.effects.set_index("system")
    for system in ("A", "B"):
        assert abs(effects.loc[system, "difference"] - EFFECTS[system]) < 3 * effects.loc[system, "se"]
        assert effects.loc[system, "odds_ratio"] == pytest.approx(np.exp(effects.loc[system, "difference"]))
    assert list(tables.thresholds["threshold"]) == ["1|2", "2|3", "3|4", "4|5"]
    spreads = tables.random_effects.set_index("component")["sd"]
    assert 0.5 < spreads["participant"] < 1.1 and 0.2 < spreads["stimulus"] < 0.8
    assert tables.random_effects["converged"].all()


def test_a_zero_clip_spread_fits_without_failing():
    table = likert(participants=30, clips=10, per_system=8, stimulus_sd=0.0, seed=12)
    tables = ordinal_mixed_model(table, reference="NAT")
    spreads = tables.random_effects.set_index("component")
    assert spreads.loc["stimulus", "sd"] < 0.2 and tables.random_effects["converged"].all()
    assert np.isfinite(tables.effects["se"]).all() and tables.notes == []


def test_ratings_that_each_equal_their_system_s_mean_are_not_fitted_and_the_notes_say_why():
    levels = {system: 1 + n for n, system in enumerate(EFFECTS)}
    exact = likert().assign(value=lambda t: t["system"].map(levels))
    tables = ordinal_mixed_model(exact)
    assert tables.effects.empty
    assert any(note.endswith("every rating equals its system's mean, so each system's ratings are one value and "
                             "the log-odds between systems are not finite.") for note in tables.notes)


def test_ratings_that_separate_the_systems_are_not_fitted_and_the_notes_say_why():
    # Each system's ratings keep to two values of their own (NAT 4-5, A 3-4, B 2-3): the
    # likelihood grows without bound as the log-odds do, so no estimate is finite.
    values = {"NAT": [4, 5, 5, 4, 4, 5], "A": [3, 4, 4, 3, 3, 4], "B": [2, 3, 3, 2, 2, 3]}
    table = pd.DataFrame([(f"p{p}", system, f"{system}_{c}", values[system][(c + p) % 6])
                          for p in range(4) for system in values for c in range(2)],
                         columns=["participant", "system", "stimulus", "value"]).assign(task="t", control_class="c")
    tables = ordinal_mixed_model(table, reference="NAT")
    assert tables.effects.empty
    assert any("the ratings separate the systems" in note and "no finite estimate" in note for note in tables.notes)
