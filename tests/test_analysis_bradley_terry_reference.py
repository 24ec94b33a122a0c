"""Bradley-Terry strengths with a reference system fixed at zero, and the covariance the
report writes out, against a logistic regression without the reference's column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import statsmodels.api as sm

from analysis import build_report, validate_ratings
from analysis.rankings.bradley_terry import bradley_terry_covariance, bradley_terry_scale, win_matrix
from analysis.cli import main
from analysis.stats.preferences import preference_pages
from analysis.ratings.simulate import simulate_pairwise

STRENGTHS = {"NAT": 1.0, "A": 0.4, "B": 0.1, "C": -0.5}


def glm_with_reference(systems: list[str], wins: np.ndarray, reference: str):
    """logit P(i beats j) = b_i - b_j with the reference's column dropped (b_ref = 0)."""
    r = systems.index(reference)
    design, outcome = [], []
    for i in range(len(systems)):
        for j in range(i + 1, len(systems)):
            if wins[i, j] + wins[j, i]:
                x = np.zeros(len(systems))
                x[i], x[j] = 1.0, -1.0
                design.append(np.delete(x, r))
                outcome.append([wins[i, j], wins[j, i]])
    fit = sm.GLM(np.array(outcome), np.array(design), family=sm.families.Binomial()).fit(tol=1e-13)
    full = np.zeros((len(systems), len(systems)))
    keep = [i for i in range(len(systems)) if i != r]
    full[np.ix_(keep, keep)] = fit.cov_params()
    return np.insert(fit.params, r, 0.0), np.insert(fit.bse, r, 0.0), full


def test_strengths_against_the_reference_equal_a_regression_without_its_column():
    pages = preference_pages(validate_ratings(simulate_pairwise(
        STRENGTHS, n_participants=80, inattentive_share=0.0, seed=3).astype(str)))
    systems, wins = win_matrix(pages)
    scale, _ = bradley_terry_scale(pages, reference="NAT")
    params, se, covariance = glm_with_reference(systems, wins, "NAT")
    scale = scale.set_index("system").loc[systems]
    assert set(scale["reference"]) == {"NAT"}
    np.testing.assert_allclose(scale["strength_vs_reference"], params, atol=1e-7)
    np.testing.assert_allclose(scale["se_vs_reference"], se, rtol=1e-5, atol=1e-12)
    # the centred covariance is the reference-fixed one moved to the sum-to-zero strengths
    centre = np.eye(len(systems)) - 1.0 / len(systems)
    written = bradley_terry_covariance(pages).pivot(index="system_a", columns="system_b",
                                                    values="covariance").loc[systems, systems]
    np.testing.assert_allclose(written, centre @ covariance @ centre.T, rtol=1e-5, atol=1e-12)


def test_the_pairwise_report_writes_the_covariance_and_the_reference_errors(tmp_path):
    table = simulate_pairwise(STRENGTHS, n_participants=40, seed=5)
    path = tmp_path / "ratings.csv"
    table.to_csv(path, index=False)
    assert main(["report", str(path), "--out", str(tmp_path / "out")]) == 0
    covariance = pd.read_csv(tmp_path / "out" / "tables" / "bradley_terry_covariance.csv")
    assert len(covariance) == 16 and {"system_a", "system_b", "covariance"} <= set(covariance.columns)
    scale = pd.read_csv(tmp_path / "out" / "tables" / "bradley_terry.csv").set_index("system")
    assert scale.loc["NAT", "se_vs_reference"] == 0 and (scale["reference"] == "NAT").all()
    report = build_report(validate_ratings(table.astype(str)), reference="A")
    assert set(report.table("bradley_terry")["reference"]) == {"A"}
