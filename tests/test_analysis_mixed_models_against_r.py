"""The crossed linear mixed model and the cumulative link mixed model against R itself:
lme4's ``lmer`` and ordinal's ``clmm`` (tests/r_mixed_models.R) on seeded simulated
studies, unbalanced (participants rate different numbers of clips, drawn at random):
a positive participant and clip variance, a zero clip variance, 2, 3 and 10 systems, and
a 300-rater study where the fits once stopped at a zero variance that R's are not at.
Each model's fixed effects and variances must equal R's, and its criterion be no worse.

R (r-base-core, r-cran-lme4, r-cran-ordinal) is installed by ``make test``
(scripts/ensure-r.sh); without Rscript these tests fail.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.raters.crossed_design import crossed_layout
from analysis.raters.crossed_mixed import fit_crossed
from analysis.raters.ordinal_mixed import fit_ordinal
from analysis.ratings.simulate import simulate_ratings

pytestmark = pytest.mark.slow

R_SCRIPT = Path(__file__).with_name("r_mixed_models.R")
LMM_TOLERANCE = 1e-4
CLMM_TOLERANCE = 2e-3
# the criteria are sums over a thousand or more ratings, each to some 1e-13
CRITERION_SLACK = 1e-6


def latent_study(systems: int, participants: int, clips: int, ratings: tuple[int, int], participant_sd: float,
                 clip_sd: float, seed: int) -> pd.DataFrame:
    """1-5 ratings of a latent logistic rating cut at four thresholds, system S0 the best;
    each participant rates between ``ratings`` clips drawn at random (a clip at most once)."""
    rng = np.random.default_rng(seed)
    effects = np.r_[0.0, -np.linspace(0.3, 1.5, systems - 1)]
    cuts = np.array([-2.5, -1.0, 0.5, 2.0])
    u = rng.normal(0, participant_sd, participants)
    v = rng.normal(0, clip_sd, (systems, clips))
    rows = []
    for p in range(participants):
        n = rng.integers(ratings[0], ratings[1] + 1)
        for s, c in set(zip(rng.integers(0, systems, n), rng.integers(0, clips, n))):
            latent = effects[s] + u[p] + v[s, c] + rng.logistic()
            rows.append((f"p{p}", f"S{s}_{c}", f"S{s}", 1 + int(np.searchsorted(cuts, latent))))
    return pd.DataFrame(rows, columns=["participant", "stimulus", "system", "value"])


def three_hundred_raters() -> pd.DataFrame:
    """One cell of a simulated single-clip study: 300 raters of 20 clips each on a 1-5
    scale, a real participant effect, no clip effect."""
    table = simulate_ratings({"NAT": 4.0, "MG": 3.6, "A": 3.0}, 6000, ratings_per_participant=20,
                             stimuli_per_system=20, seed=1)
    return table[(table["system"] != "BAD") & (table["control_class"] == "held-out")]


# name -> (ratings, the reference system, which variances R puts above zero: participant, stimulus)
CASES = {
    "300_raters_participant_effect": (three_hundred_raters, "NAT", (True, True)),
    "2_systems_participant_and_clip_effects": (lambda: latent_study(2, 60, 10, (5, 40), 0.8, 0.3, seed=1), "S0",
                                               (True, True)),
    "3_systems_no_clip_effect": (lambda: latent_study(3, 60, 10, (5, 40), 0.8, 0.0, seed=2), "S0", (True, False)),
    "10_systems_participant_and_clip_effects": (lambda: latent_study(10, 40, 4, (5, 30), 0.8, 0.3, seed=0), "S0",
                                                (True, True)),
}


@pytest.fixture(scope="module")
def studies(tmp_path_factory) -> dict[str, tuple[pd.DataFrame, pd.Series, pd.Series]]:
    """name -> (ratings, lmer's terms, clmm's terms), R run once over every case; the
    reference system first in the ratings, as R takes it."""
    assert shutil.which("Rscript"), ("Rscript is missing: make test installs R with lme4 and ordinal "
                                     "(scripts/ensure-r.sh)")
    folder = tmp_path_factory.mktemp("r")
    tables = {}
    for name, (make, reference, _) in CASES.items():
        table = make()[["participant", "stimulus", "system", "value"]]
        tables[name] = table.sort_values("system", key=lambda s: s != reference, kind="stable")
        tables[name].to_csv(folder / f"{name}.csv", index=False)
    finished = subprocess.run(["Rscript", str(R_SCRIPT), str(folder)], capture_output=True, text=True, timeout=900)
    assert finished.returncode == 0, finished.stderr
    read = lambda path: pd.read_csv(path).set_index("term")["estimate"]  # noqa: E731
    return {name: (table, read(folder / f"{name}.lmer.csv"), read(folder / f"{name}.clmm.csv"))
            for name, table in tables.items()}


def positive(variances: pd.Series) -> tuple[bool, bool]:
    return tuple(bool(variances[f"{factor}_var"] > 1e-6) for factor in ("participant", "stimulus"))


@pytest.mark.parametrize("case", CASES)
def test_the_crossed_lmm_equals_lme4s_lmer(studies, case):
    table, lmer, _ = studies[case]
    assert positive(lmer) == CASES[case][2]  # the case covers what it is named after
    layout = crossed_layout(table, CASES[case][1])
    fit = fit_crossed(table["value"].to_numpy(np.float64), layout)
    np.testing.assert_allclose(fit.estimate, lmer[layout.systems], rtol=0, atol=LMM_TOLERANCE)
    np.testing.assert_allclose([fit.participant_var, fit.stimulus_var, fit.residual_var],
                               lmer[["participant_var", "stimulus_var", "residual_var"]], rtol=0, atol=LMM_TOLERANCE)
    assert fit.deviance <= lmer["reml_criterion"] + CRITERION_SLACK
    # a variance is reported as zero exactly where lme4's optimum has it
    assert (fit.participant_var > 0, fit.stimulus_var > 0) == (lmer["participant_var"] > 0, lmer["stimulus_var"] > 0)


@pytest.mark.parametrize("case", CASES)
def test_the_cumulative_link_mixed_model_equals_ordinals_clmm(studies, case):
    table, _, clmm = studies[case]
    assert positive(clmm) == CASES[case][2]
    layout = crossed_layout(table, CASES[case][1])
    fit = fit_ordinal(table["value"].to_numpy(), layout)
    names = [f"{a}|{b}" for a, b in zip(fit.categories[:-1], fit.categories[1:])]
    np.testing.assert_allclose(np.r_[fit.thresholds, fit.effects[1:]], clmm[names + layout.systems[1:]],
                               rtol=0, atol=CLMM_TOLERANCE)
    np.testing.assert_allclose([fit.participant_sd**2, fit.stimulus_sd**2],
                               clmm[["participant_var", "stimulus_var"]], rtol=0, atol=CLMM_TOLERANCE)
    assert fit.log_likelihood >= clmm["log_likelihood"] - CRITERION_SLACK
    assert (fit.participant_sd > 0, fit.stimulus_sd > 0) == positive(clmm)
