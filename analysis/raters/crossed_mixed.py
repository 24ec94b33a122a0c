"""The crossed random-effects linear mixed model of ratings, by REML, as lme4 fits
``value ~ system + (1 | participant) + (1 | stimulus)``.

Ratings are clustered twice: a participant rates many clips (lenient and strict raters)
and a clip is rated by many participants (some clips of a system are better than
others). The model

    y = X b + Z_p u + Z_s v + e,   u ~ N(0, s_p^2), v ~ N(0, s_s^2), e ~ N(0, s^2)

codes the systems as cell means (one column of X per system, no intercept), so b_k is
system k's rating for an average participant on an average clip, and the contrasts
against the reference system are b_k - b_ref with Wald z tests, Holm-adjusted over the
systems (as statsmodels' MixedLM reports; lme4 gives no p-values, lmerTest's
Satterthwaite t is a little more conservative with few participants).

Fit (Bates, Maechler, Bolker & Walker 2015, "Fitting linear mixed-effects models using
lme4", Sec. 3). The random effects are ``Lambda w`` with ``w ~ N(0, s^2 I)`` and the
relative covariance factor ``Lambda = diag(t_p I, t_s I)``, ``t = (s_p / s, s_s / s)``.
For a given t, the penalised least squares problem

    min over b, w of  ||y - X b - Z Lambda w||^2 + ||w||^2

has the normal equations ``M w + Lambda Z'X b = Lambda Z'y`` and
``X'Z Lambda w + X'X b = X'y`` with ``M = Lambda Z'Z Lambda + I``. Eliminating w:
``R = X'X - X'Z Lambda M^-1 Lambda Z'X`` and ``R b = X'y - X'Z Lambda M^-1 Lambda Z'y``;
the penalised residual sum of squares is ``r^2 = y'y - w'Lambda Z'y - b'X'y``. The REML
criterion, profiled over b and s^2, is

    -2 l_R(t) = log|M| + log|R| + (n - k) (1 + log(2 pi r^2 / (n - k))),

minimised over t >= 0. It depends on t through Lambda's squares only (t and -t give the
same model), so its gradient in a component at 0 is zero and an optimiser bounded at 0
would stop wherever it steps onto the bound; it is minimised over both signs instead
(L-BFGS-B from t = 1, as lme4 starts), where a component at 0 is a minimum like any
other, and |t| kept. A variance component estimated at zero sits on its bound
(``at_boundary``): the model is then the one without that factor, and the fit does not
fail. At the optimum ``s^2 = r^2 / (n - k)`` and ``Var(b) = s^2 R^-1``.

Speed: Z'Z has diagonal blocks (`analysis.raters.crossed_design`), so M is factorised through
the Schur complement of its smaller block, and every quantity is a function of sums per
participant, stimulus and system: an evaluation costs the same for 700 or 70,000
ratings. The tests check the fit against lme4's ``lmer`` run in R, statsmodels' MixedLM
with variance components for the two factors, and the REML likelihood written with the
n x n covariance matrix and maximised by scipy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import optimize
from scipy import stats as sps

from analysis.raters.crossed_design import (CrossedBlocks, CrossedLayout, contrasts_against_reference,
                                     crossed_layout)
from analysis.blas import one_blas_thread
from analysis.errors import AnalysisInputError
from analysis.stats.anova import CELL, iter_cells

_MAX_RELATIVE_SD = 1e3


@dataclass(frozen=True)
class _Sums:
    """The sufficient statistics of one cell."""

    layout: CrossedLayout
    n: int
    yy: float
    xy: np.ndarray  # per system
    xx: np.ndarray  # ratings per system
    zy: tuple[np.ndarray, np.ndarray]  # per participant, per stimulus
    zx: tuple[np.ndarray, np.ndarray]  # (levels, systems) counts
    zz: tuple[np.ndarray, np.ndarray, np.ndarray]  # counts per participant, stimulus, occurring pair


def _sums(y: np.ndarray, layout: CrossedLayout) -> _Sums:
    k = len(layout.systems)
    q_p, q_s = layout.q
    ones = np.ones(len(y))
    n_p, n_s, n_ps = layout.sums(ones)
    y_p, y_s, _ = layout.sums(y)
    return _Sums(layout, len(y), float(y @ y), np.bincount(layout.system, y, k),
                 np.bincount(layout.system, minlength=k).astype(np.float64), (y_p, y_s),
                 (layout.by_system(layout.participant, q_p), layout.by_system(layout.stimulus, q_s)),
                 (n_p, n_s, n_ps))


@dataclass(frozen=True)
class _Solution:
    deviance: float
    beta: np.ndarray
    r: np.ndarray
    rss: float


def _solve(t: np.ndarray, s: _Sums) -> _Solution:
    """The penalised least-squares solution and REML deviance at relative sds ``t``."""
    t_p, t_s = t
    n_p, n_s, n_ps = s.zz
    blocks = CrossedBlocks(s.layout, t_p**2 * n_p + 1.0, t_p * t_s * n_ps, t_s**2 * n_s + 1.0)
    lzy = (t_p * s.zy[0], t_s * s.zy[1])
    lzx = (t_p * s.zx[0], t_s * s.zx[1])
    wy = blocks.solve(*lzy)
    wx = blocks.solve(*lzx)
    r = np.diag(s.xx) - lzx[0].T @ wx[0] - lzx[1].T @ wx[1]
    beta = np.linalg.solve(r, s.xy - lzx[0].T @ wy[0] - lzx[1].T @ wy[1])
    w = (wy[0] - wx[0] @ beta, wy[1] - wx[1] @ beta)
    rss = s.yy - w[0] @ lzy[0] - w[1] @ lzy[1] - beta @ s.xy
    dof = s.n - len(beta)
    deviance = blocks.logdet() + np.linalg.slogdet(r)[1] + dof * (1 + np.log(2 * np.pi * rss / dof))
    return _Solution(float(deviance), beta, r, float(rss))


def reml_deviance(t: Sequence[float], y: np.ndarray, layout: CrossedLayout) -> float:
    """-2 times the REML log-likelihood at relative standard deviations ``t`` =
    (participant sd / residual sd, stimulus sd / residual sd), profiled over b and s^2."""
    return _solve(np.asarray(t, dtype=np.float64), _sums(y, layout)).deviance


@dataclass(frozen=True)
class CrossedFit:
    """One cell's fit: systems (reference first), their means and covariance, the
    variance components, and the REML deviance."""

    systems: list[str]
    estimate: np.ndarray
    covariance: np.ndarray
    participant_var: float
    stimulus_var: float
    residual_var: float
    deviance: float
    levels: tuple[int, int]


def fit_crossed(y: np.ndarray, layout: CrossedLayout) -> CrossedFit:
    """REML fit of one cell's ratings (see the module docstring)."""
    if len(y) <= len(layout.systems):
        raise AnalysisInputError(f"{len(y)} ratings of {len(layout.systems)} systems leave no "
                                 "residual degrees of freedom")
    y = np.asarray(y, dtype=np.float64)
    if layout.constant_within_systems(y):
        raise AnalysisInputError("every rating equals its system's mean, which leaves no variance for "
                                 "participants, clips or the residual to explain")
    s = _sums(y, layout)
    objective = lambda t: _solve(t, s).deviance  # noqa: E731
    # over both signs, from t = 1 as lme4 starts: bounded at 0, where the gradient vanishes,
    # the search stops wherever it steps onto the bound (module docstring)
    best = optimize.minimize(objective, (1.0, 1.0), method="L-BFGS-B",
                             bounds=[(-_MAX_RELATIVE_SD, _MAX_RELATIVE_SD)] * 2,
                             options={"ftol": 1e-15, "gtol": 1e-9, "maxiter": 500})
    t = np.abs(best.x)
    for axis in range(2):  # a component the optimiser left a hair above zero belongs at zero
        at_zero = t.copy()
        at_zero[axis] = 0.0
        if objective(at_zero) <= best.fun + 1e-9:
            t = at_zero
    solution = _solve(t, s)
    residual_var = solution.rss / (s.n - len(solution.beta))
    return CrossedFit(layout.systems, solution.beta, residual_var * np.linalg.inv(solution.r),
                      residual_var * t[0] ** 2, residual_var * t[1] ** 2, residual_var,
                      solution.deviance, layout.q)


@dataclass
class CrossedModelTables:
    """The crossed LMM of every cell as tidy tables."""

    estimates: pd.DataFrame
    contrasts: pd.DataFrame
    variance_components: pd.DataFrame
    notes: list[str] = field(default_factory=list)


def crossed_mixed_model(data: pd.DataFrame, reference: str | None = None, dv: str = "value",
                        between: str = "system", participant: str = "participant",
                        stimulus: str = "stimulus", groupby: Sequence[str] = CELL,
                        alpha: float = 0.05, confidence: float = 0.95) -> CrossedModelTables:
    """Fit ``dv ~ between + (1 | participant) + (1 | stimulus)`` by REML per cell.

    ``estimates``: *groupby, system, n, estimate, se, ci_low, ci_high (Wald).
    ``contrasts``: *groupby, system, reference, difference, se, ci_low, ci_high, z, p,
    p_holm (over the cell's contrasts), reject. The reference defaults to the first system
    in sorted order where ``reference`` was not rated in a cell (a note says so).
    ``variance_components``: *groupby, component (participant, stimulus, residual),
    levels, variance, sd, share (of the total variance), at_boundary (estimated at zero).
    """
    z = sps.norm.ppf(0.5 + confidence / 2)
    estimates, contrasts, components, notes = [], [], [], []
    for key, frame in iter_cells(data, groupby):
        where = " · ".join(map(str, key.values())) or "all ratings"
        chosen = reference if reference in set(frame[between]) else None
        if reference is not None and chosen is None:
            notes.append(f"Crossed mixed model, {where}: {reference} was not rated; contrasts "
                         "are against the first system in sorted order.")
        layout = crossed_layout(frame, chosen, between, participant, stimulus)
        try:
            with one_blas_thread():
                fit = fit_crossed(frame[dv].to_numpy(np.float64), layout)
        except (AnalysisInputError, np.linalg.LinAlgError) as exc:
            notes.append(f"No crossed mixed model for {where}: {exc}.")
            continue
        se = np.sqrt(np.diag(fit.covariance))
        counts = np.bincount(layout.system, minlength=len(fit.systems))
        estimates.append(pd.DataFrame({**key, "system": fit.systems, "n": counts, "estimate": fit.estimate,
                                       "se": se, "ci_low": fit.estimate - z * se,
                                       "ci_high": fit.estimate + z * se}))
        contrasts.append(contrasts_against_reference(fit.estimate, fit.covariance, fit.systems,
                                                     alpha, confidence).assign(**key))
        variance = np.array([fit.participant_var, fit.stimulus_var, fit.residual_var])
        components.append(pd.DataFrame({**key, "component": [participant, stimulus, "residual"],
                                        "levels": [*fit.levels, len(frame)], "variance": variance,
                                        "sd": np.sqrt(variance), "share": variance / variance.sum(),
                                        "at_boundary": [fit.participant_var == 0, fit.stimulus_var == 0, False]}))
        if fit.participant_var == 0 or fit.stimulus_var == 0:
            zero = [name for name, v in ((participant, fit.participant_var), (stimulus, fit.stimulus_var)) if v == 0]
            notes.append(f"Crossed mixed model, {where}: the {' and '.join(zero)} variance was "
                         "estimated at zero (a boundary fit: the model reduces to the one without it).")
    columns = {"contrasts": [*groupby, "system", "reference", "difference", "se", "ci_low", "ci_high",
                             "z", "p", "p_holm", "reject"]}
    joined = [pd.concat(t, ignore_index=True) if t else pd.DataFrame() for t in (estimates, contrasts, components)]
    if len(joined[1]):
        joined[1] = joined[1][columns["contrasts"]]
    return CrossedModelTables(*joined, notes)
