"""A rater-aware alternative to the ANOVA: a linear mixed model with participant intercepts.

Ratings are nested in participants, so they are not independent. The model is

    value = beta[system] + u[participant] + e,   u ~ N(0, sigma_u^2),  e ~ N(0, sigma^2)

fitted by REML. With no intercept term, beta[system] is the estimated marginal mean of
that system (participant effect at zero), reported with a Wald 95 % interval exactly as
statsmodels' MixedLM(value ~ 0 + C(system), groups=participant) does; the tests check
the two agree.

Why not call MixedLM directly: its fit loops over participants in Python, about 1.6 s
for 25,000 ratings, too slow for a full report within the benchmark's 5 s. With a single
random intercept every quantity the REML likelihood needs is a function of per-participant
sums, so the likelihood is profiled down to one variable (gamma = sigma_u^2 / sigma^2)
and maximised by a bounded scalar search in milliseconds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import optimize
from scipy import stats as sps

from analysis.stats.anova import CELL, iter_cells

_LOG_GAMMA_BOUNDS = (-18.0, 8.0)


def _sufficient_statistics(y: np.ndarray, system: np.ndarray, group: np.ndarray, k: int, g: int):
    counts = np.bincount(group * k + system, minlength=g * k).reshape(g, k).astype(np.float64)
    return {
        "counts": counts,  # ratings per participant and system
        "group_n": counts.sum(axis=1),
        "group_sum": np.bincount(group, weights=y, minlength=g),
        "system_n": counts.sum(axis=0),
        "system_sum": np.bincount(system, weights=y, minlength=k),
        "yy": float(y @ y),
        "n": len(y),
        "k": k,
    }


def _profiled(gamma: float, s: dict):
    """A = X'H X, beta, residual sum of squares and -2 REML log-likelihood (up to a constant)."""
    w = gamma / (1.0 + gamma * s["group_n"])
    a = np.diag(s["system_n"]) - (s["counts"] * w[:, None]).T @ s["counts"]
    b = s["system_sum"] - s["counts"].T @ (w * s["group_sum"])
    beta = np.linalg.solve(a, b)
    rss = s["yy"] - float(w @ s["group_sum"] ** 2) - float(b @ beta)
    dof = s["n"] - s["k"]
    minus2 = (dof * np.log(rss / dof) + np.log1p(gamma * s["group_n"]).sum()
              + np.linalg.slogdet(a)[1])
    return a, beta, rss, minus2


def mixed_model_means(data: pd.DataFrame, dv: str = "value", between: str = "system",
                      participant: str = "participant", groupby: Sequence[str] = CELL,
                      confidence: float = 0.95) -> pd.DataFrame:
    """Per-system estimated marginal means of the random-intercept model, per cell.

    Columns: *groupby, system, estimate, se, ci_low, ci_high, participant_var,
    residual_var, n_participants, at_boundary (participant variance estimated at zero,
    where the model reduces to the ordinary means).
    """
    rows = []
    z = sps.norm.ppf(0.5 + confidence / 2)
    for key, frame in iter_cells(data, groupby):
        system_idx, systems = pd.factorize(frame[between], sort=True)
        group_idx, groups = pd.factorize(frame[participant])
        s = _sufficient_statistics(frame[dv].to_numpy(np.float64), system_idx, group_idx,
                                   len(systems), len(groups))
        found = optimize.minimize_scalar(lambda t: _profiled(np.exp(t), s)[3],
                                         bounds=_LOG_GAMMA_BOUNDS, method="bounded",
                                         options={"xatol": 1e-8})
        gamma = float(np.exp(found.x))
        # a flat or decreasing likelihood towards gamma = 0 means no participant variance
        at_boundary = _profiled(0.0, s)[3] <= found.fun + 1e-9
        if at_boundary:
            gamma = 0.0
        a, beta, rss, _ = _profiled(gamma, s)
        residual_var = rss / (s["n"] - s["k"])
        se = np.sqrt(residual_var * np.diag(np.linalg.inv(a)))
        rows.append(pd.DataFrame({**key, between: np.asarray(systems), "estimate": beta, "se": se,
                                  "ci_low": beta - z * se, "ci_high": beta + z * se,
                                  "participant_var": gamma * residual_var,
                                  "residual_var": residual_var,
                                  "n_participants": len(groups), "at_boundary": at_boundary}))
    return pd.concat(rows, ignore_index=True)
