"""The crossed random-effects LMM against independent computations: the REML likelihood
written with the n x n covariance matrix and maximised by scipy, statsmodels' MixedLM
with variance components, and the project's participant-only REML at the boundary."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from scipy import optimize
from statsmodels.stats.multitest import multipletests

from analysis.raters.crossed_design import crossed_layout
from analysis.raters.crossed_mixed import crossed_mixed_model, fit_crossed, reml_deviance
from analysis.raters.mixed import mixed_model_means

MEANS = {"NAT": 4.0, "A": 3.2, "B": 3.0}


def ratings(participant_sd: float = 0.6, stimulus_sd: float = 0.4, participants: int = 12,
            clips: int = 10, per_system: int = 6, seed: int = 1) -> pd.DataFrame:
    """Each participant rates ``per_system`` of each system's ``clips`` clips."""
    rng = np.random.default_rng(seed)
    u = rng.normal(0, participant_sd, participants)
    v = rng.normal(0, stimulus_sd, (len(MEANS), clips))
    rows = [(f"p{p}", system, f"{system}_{c}", mean + u[p] + v[s, c] + rng.normal(0, 0.8))
            for p in range(participants) for s, (system, mean) in enumerate(MEANS.items())
            for c in rng.choice(clips, per_system, replace=False)]
    table = pd.DataFrame(rows, columns=["participant", "system", "stimulus", "value"])
    return table.assign(task="t", control_class="c")


def dense_reml(log_sds: np.ndarray, table: pd.DataFrame) -> float:
    """-log REML likelihood from V = s_p^2 Z_p Z_p' + s_s^2 Z_s Z_s' + s^2 I directly."""
    s_p, s_s, s_e = np.exp(log_sds)
    y = table["value"].to_numpy()
    x, p_p, p_s = table.attrs["dense"]  # the design and the two factors' Z Z'
    v = s_p**2 * p_p + s_s**2 * p_s + s_e**2 * np.eye(len(y))
    v_inv = np.linalg.inv(v)
    xvx = x.T @ v_inv @ x
    b = np.linalg.solve(xvx, x.T @ v_inv @ y)
    r = y - x @ b
    return 0.5 * (np.linalg.slogdet(v)[1] + np.linalg.slogdet(xvx)[1] + r @ v_inv @ r
                  + (len(y) - x.shape[1]) * np.log(2 * np.pi))


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    table = ratings(participants=10, clips=8, per_system=5)
    z_p, z_s = (pd.get_dummies(table[c]).to_numpy(float) for c in ("participant", "stimulus"))
    table.attrs["dense"] = (pd.get_dummies(table["system"]).to_numpy(float), z_p @ z_p.T, z_s @ z_s.T)
    return table


@pytest.mark.parametrize("relative_sds", [(0.5, 0.3), (1.0, 0.0), (0.0, 0.0), (0.2, 1.5)])
def test_the_profiled_deviance_equals_the_dense_reml_likelihood(table, relative_sds):
    layout = crossed_layout(table, "NAT")
    t_p, t_s = relative_sds
    # profile the dense likelihood over the residual sd at the same ratios
    profiled = optimize.minimize_scalar(
        lambda log_s: dense_reml(np.array([np.log(max(t_p, 1e-300)), np.log(max(t_s, 1e-300)), 0.0]) + log_s, table),
        bounds=(-4, 3), method="bounded", options={"xatol": 1e-11})
    assert reml_deviance(relative_sds, table["value"].to_numpy(), layout) == pytest.approx(2 * profiled.fun, rel=1e-10)


def test_the_fit_equals_the_maximum_of_the_dense_reml_likelihood(table):
    fit = fit_crossed(table["value"].to_numpy(), crossed_layout(table, "NAT"))
    found = optimize.minimize(dense_reml, np.log([0.5, 0.5, 0.8]), args=(table,), method="BFGS",
                              options={"gtol": 1e-9})
    np.testing.assert_allclose([fit.participant_var, fit.stimulus_var, fit.residual_var],
                               np.exp(2 * found.x), rtol=1e-5)
    # generalised least squares at those variances: b = (X'V^-1 X)^-1 X'V^-1 y, Var(b) = (X'V^-1 X)^-1
    x, p_p, p_s = table.attrs["dense"]
    v_inv = np.linalg.inv(fit.participant_var * p_p + fit.stimulus_var * p_s
                          + fit.residual_var * np.eye(len(table)))
    covariance = np.linalg.inv(x.T @ v_inv @ x)
    order = [sorted(MEANS).index(s) for s in fit.systems]  # the dummies' columns are sorted
    gls = (covariance @ x.T @ v_inv @ table["value"].to_numpy())[order]
    np.testing.assert_allclose(fit.estimate, gls, atol=1e-9)
    np.testing.assert_allclose(fit.covariance, covariance[np.ix_(order, order)], rtol=1e-9)


def test_the_fit_equals_statsmodels_mixedlm_with_crossed_variance_components(table):
    tables = crossed_mixed_model(table, reference="NAT")
    model = sm.MixedLM.from_formula("value ~ 0 + C(system)", groups=np.ones(len(table)), data=table,
                                    vc_formula={"participant": "0 + C(participant)",
                                                "stimulus": "0 + C(stimulus)"})
    reference = model.fit(reml=True, method="lbfgs")
    ours = tables.estimates.set_index("system")
    names = [f"C(system)[{s}]" for s in ours.index]
    np.testing.assert_allclose(ours["estimate"], reference.fe_params[names], atol=1e-6)
    # statsmodels' errors invert the information of every parameter, variances included
    np.testing.assert_allclose(ours["se"], reference.bse_fe[names], rtol=1e-2)
    components = tables.variance_components.set_index("component")["variance"]
    vcomp = dict(zip(model.exog_vc.names, reference.vcomp))
    assert components["participant"] == pytest.approx(vcomp["participant"], rel=1e-4)
    assert components["stimulus"] == pytest.approx(vcomp["stimulus"], rel=1e-4)
    assert components["residual"] == pytest.approx(reference.scale, rel=1e-4)


def test_contrasts_are_differences_from_the_reference_with_holm(table):
    tables = crossed_mixed_model(table, reference="NAT")
    fit = fit_crossed(table["value"].to_numpy(), crossed_layout(table, "NAT"))
    contrasts = tables.contrasts.set_index("system")
    for i, system in enumerate(fit.systems[1:], start=1):
        assert contrasts.loc[system, "difference"] == pytest.approx(fit.estimate[i] - fit.estimate[0])
        variance = fit.covariance[i, i] + fit.covariance[0, 0] - 2 * fit.covariance[0, i]
        assert contrasts.loc[system, "se"] == pytest.approx(np.sqrt(variance))
    np.testing.assert_allclose(contrasts["p_holm"], multipletests(contrasts["p"], method="holm")[1])
    assert set(contrasts["reference"]) == {"NAT"} and contrasts["reject"].all()


def test_a_zero_clip_variance_is_a_boundary_fit_equal_to_the_participant_only_model():
    # without a clip effect REML puts its variance on the bound in about half the samples; this one does
    flat = ratings(stimulus_sd=0.0, seed=4)
    tables = crossed_mixed_model(flat, reference="NAT")
    components = tables.variance_components.set_index("component")
    assert components.loc["stimulus", "variance"] == 0.0 and components.loc["stimulus", "at_boundary"]
    assert any("stimulus variance was estimated at zero" in note for note in tables.notes)
    participant_only = mixed_model_means(flat).set_index("system")
    ours = tables.estimates.set_index("system")
    np.testing.assert_allclose(ours["estimate"], participant_only.loc[ours.index, "estimate"], atol=1e-6)
    np.testing.assert_allclose(ours["se"], participant_only.loc[ours.index, "se"], rtol=1e-5)
    assert components.loc["participant", "variance"] == pytest.approx(
        participant_only["participant_var"].iloc[0], rel=1e-5)


def test_clips_rated_once_fit_without_failing_and_share_the_residual_variance():
    rng = np.random.default_rng(5)
    offset = rng.normal(0, 0.5, 30)
    rows = [(f"p{p}", s, f"{s}_{p}", m + offset[p] + rng.normal(0, 1.0))
            for p in range(30) for s, m in MEANS.items()]
    table = pd.DataFrame(rows, columns=["participant", "system", "stimulus", "value"]).assign(
        task="t", control_class="c")
    # one rating per clip: only the sum of the clip and residual variances is identified
    tables = crossed_mixed_model(table)
    components = tables.variance_components.set_index("component")["variance"]
    participant_only = mixed_model_means(table).set_index("system")
    assert components["stimulus"] + components["residual"] == pytest.approx(
        participant_only["residual_var"].iloc[0], rel=1e-5)
    ours = tables.estimates.set_index("system")
    np.testing.assert_allclose(ours["estimate"], participant_only.loc[ours.index, "estimate"], atol=1e-6)
    np.testing.assert_allclose(ours["se"], participant_only.loc[ours.index, "se"], rtol=1e-5)


def test_ratings_that_each_equal_their_system_s_mean_are_not_fitted_and_the_notes_say_why():
    exact = ratings().assign(value=lambda t: t["system"].map(MEANS))
    with np.errstate(all="raise"):  # no 0/0 or log(0) on the way
        tables = crossed_mixed_model(exact, reference="NAT")
    assert tables.estimates.empty and tables.variance_components.empty
    assert tables.notes == ["No crossed mixed model for t · c: every rating equals its system's mean, which "
                            "leaves no variance for participants, clips or the residual to explain."]
