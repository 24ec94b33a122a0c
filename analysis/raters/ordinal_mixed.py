"""The cumulative link (logit) mixed model of Likert ratings, as R's ordinal::clmm fits
``value ~ system + (1 | participant) + (1 | stimulus)`` by the Laplace approximation.

Model. A rating y in the ordered categories c_1 < ... < c_J (the values used) with

    P(y <= c_j) = F(alpha_j - eta),   eta = beta[system] + s_p u[participant] + s_s v[stimulus],

F the logistic distribution function, u, v ~ N(0, 1), alpha_1 < ... < alpha_{J-1} the
thresholds, beta = 0 for the reference system (treatment coding), so beta_k is the shift
of system k's latent rating against the reference in logits: exp(beta_k) is the odds
ratio of a higher rating. s_p and s_s are the random intercepts' standard deviations
(the latent residual's is pi / sqrt(3)).

Laplace approximation. With w = (u, v) (q = q_p + q_s of them), Lambda = diag(s_p I,
s_s I) and g(w) = sum_i log pi_i(eta_i) - |w|^2 / 2, the log-likelihood is
``log integral exp(g) dw - q/2 log 2 pi``, approximated as

    L = g(w*) - 1/2 log|H|,   H = I + Lambda Z' D Z Lambda,   D_i = -d^2 log pi_i / d eta^2,

at the mode w* of g, found by Newton's method (g is concave: log pi is concave in eta for
the logit link). H has the crossed block structure of `analysis.raters.crossed_design`, so it
is factorised through the Schur complement of its smaller block. Writing the random
effects as Lambda w keeps L defined at s = 0: a variance component estimated at zero
sits on its bound (``at_boundary``) and the fit does not fail.

Gradient. L is maximised over theta = (alpha, beta, s_p, s_s) by L-BFGS-B (the
thresholds through alpha_1 and the logs of their increments, which keeps them in order;
each s over both signs: s and -s are the same model, and L's derivative in s is zero at
s = 0, where an optimiser bounded at 0 would stop whatever the optimum; |s| is kept)
with the exact gradient of the approximation: at the mode dg/dw = 0, so

    dL/dtheta = dg/dtheta|_w* - 1/2 tr(H^-1 dH/dtheta),

where dH/dtheta holds D's change (directly, and through eta with the mode's own change
dw*/dtheta = H^-1 d(dg/dw)/dtheta) and, for s, Lambda's. With per-rating derivatives of
log pi up to the third order, every term is a sum over ratings or a solve with H; the
tests compare it with finite differences.

Separation. Where the ratings separate the systems (each system's ratings keeping to
values of their own), the likelihood grows as log-odds run off to infinity and no
estimate is finite. The thresholds and effects are bounded at +/- ``_MAX_LOGIT``, far
beyond anything ratings can estimate, so the fit stops there; an estimate on that bound
is reported as no fit, with the reason, instead of as a number.

Standard errors: from the inverse of the numerical Hessian (forward differences of the
exact gradient, accurate to about 1e-5 relative) of -L in (alpha, beta) and the standard
deviations that are not on their bound, as ordinal does for clmm's fixed effects.

The tests check the fit against ordinal's ``clmm`` run in R, statsmodels' OrderedModel
when the random effects are left out, the Laplace approximation against one computed
independently with dense matrices and scipy, and, with one random factor, the estimates
against the exact marginal likelihood integrated numerically.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import optimize
from scipy.special import expit

from analysis.raters.crossed_design import (CrossedBlocks, CrossedLayout, contrasts_against_reference,
                                     crossed_layout)
from analysis.blas import one_blas_thread
from analysis.errors import AnalysisInputError
from analysis.stats.anova import CELL, iter_cells

RANDOM_FACTORS = ("participant", "stimulus")
_MODE_TOLERANCE = 1e-10
_MAX_MODE_STEPS = 100
_MAX_SD = 20.0
# No rating data estimate a log-odds this large (a probability of e^-30 needs some 10^13
# ratings to show): an estimate reaching it is one that grows without bound, because
# the ratings separate the systems, and the fit stops there instead of following it.
_MAX_LOGIT = 30.0
_OUTER_END = 1e4
# Where an sd's optimum is 0 the optimiser ends within some 1e-5 of it (L curves up from
# there); only sds below this are checked against 0, each check a Laplace fit.
_HAIR = 1e-3


@dataclass(frozen=True)
class _Link:
    """Per rating: log pi and its derivatives in eta; with ``full``, also the third and
    those in the rating's upper and lower threshold (a = alpha_y - eta, b = alpha_{y-1} - eta)."""

    log_pi: np.ndarray
    psi: np.ndarray  # d log pi / d eta
    d: np.ndarray  # -d2 log pi / d eta2
    d_eta: np.ndarray | None = None  # dD / d eta
    upper: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # d/da of (log pi, psi, D)
    lower: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # d/db of (log pi, psi, D)


def _link(eta: np.ndarray, upper_alpha: np.ndarray, lower_alpha: np.ndarray, full: bool = False) -> _Link:
    a, b = upper_alpha - eta, lower_alpha - eta
    Fa, Fb = expit(a), expit(b)
    fa, fb = Fa * (1 - Fa), Fb * (1 - Fb)
    fa1, fb1 = fa * (1 - 2 * Fa), fb * (1 - 2 * Fb)
    # both ends in the upper tail: S(b) - S(a) with S = 1 - F keeps the digits F(a) - F(b) loses
    pi = np.maximum(np.where(b > 0, expit(-b) - expit(-a), Fa - Fb), 1e-300)
    g1, g2 = (fa - fb) / pi, (fa1 - fb1) / pi
    d = g1**2 - g2
    if not full:
        return _Link(np.log(pi), -g1, d)
    fa2, fb2 = fa * (1 - 6 * Fa + 6 * Fa**2), fb * (1 - 6 * Fb + 6 * Fb**2)
    g3 = (fa2 - fb2) / pi
    g1_a, g2_a = (fa1 - g1 * fa) / pi, (fa2 - g2 * fa) / pi
    g1_b, g2_b = (-fb1 + g1 * fb) / pi, (-fb2 + g2 * fb) / pi
    return _Link(np.log(pi), -g1, d, 2 * g1**3 - 3 * g1 * g2 + g3,
                 (fa / pi, -g1_a, 2 * g1 * g1_a - g2_a),
                 (-fb / pi, -g1_b, 2 * g1 * g1_b - g2_b))


@dataclass
class _Data:
    layout: CrossedLayout
    category: np.ndarray  # 0 .. J-1
    levels: int  # J
    free: tuple[bool, bool]  # which random factors are in the model

    @property
    def k(self) -> int:
        return len(self.layout.systems)


def _split(theta: np.ndarray, data: _Data):
    j = data.levels - 1
    return theta[:j], np.r_[0.0, theta[j:j + data.k - 1]], theta[j + data.k - 1:]


def _threshold_ends(alpha: np.ndarray, category: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rating's upper and lower threshold; the outer ones at -/+ _OUTER_END, where the
    logistic is 0 or 1 and its derivatives 0 in floating point, as at infinity."""
    ends = np.r_[-_OUTER_END, alpha, _OUTER_END]
    return ends[category + 1], ends[category]


@dataclass
class _Laplace:
    value: float
    mode: tuple[np.ndarray, np.ndarray]
    link: _Link
    eta: np.ndarray
    blocks: CrossedBlocks


def _laplace(theta: np.ndarray, data: _Data, start: tuple[np.ndarray, np.ndarray] | None = None) -> _Laplace:
    """The Laplace approximation of the log-likelihood at natural parameters ``theta``
    (alpha, beta without the reference, s_p, s_s), with the mode of the random effects."""
    alpha, beta, (s_p, s_s) = _split(theta, data)
    lay = data.layout
    q_p, q_s = lay.q
    upper, lower = _threshold_ends(alpha, data.category)
    fixed = beta[lay.system]
    u, v = start if start is not None else (np.zeros(q_p), np.zeros(q_s))

    def at(u, v):
        eta = fixed + s_p * u[lay.participant] + s_s * v[lay.stimulus]
        link = _link(eta, upper, lower)
        return eta, link, link.log_pi.sum() - 0.5 * (u @ u + v @ v)

    eta, link, g = at(u, v)
    for _ in range(_MAX_MODE_STEPS):
        d_p, d_s, d_ps = lay.sums(link.d)
        blocks = CrossedBlocks(lay, 1 + s_p**2 * d_p, s_p * s_s * d_ps, 1 + s_s**2 * d_s)
        psi_p, psi_s, _ = lay.sums(link.psi)
        step_u, step_v = blocks.solve(s_p * psi_p - u, s_s * psi_s - v)
        scale = 1.0
        for _ in range(50):
            new = at(u + scale * step_u, v + scale * step_v)
            if new[2] >= g - 1e-12 * abs(g):
                break
            scale /= 2
        u, v = u + scale * step_u, v + scale * step_v
        eta, link, g = new
        if max(np.abs(step_u).max(initial=0), np.abs(step_v).max(initial=0)) * scale < _MODE_TOLERANCE:
            break
    d_p, d_s, d_ps = lay.sums(link.d)
    blocks = CrossedBlocks(lay, 1 + s_p**2 * d_p, s_p * s_s * d_ps, 1 + s_s**2 * d_s)
    return _Laplace(g - 0.5 * blocks.logdet(), (u, v), _link(eta, upper, lower, full=True), eta, blocks)


def _gradient(theta: np.ndarray, data: _Data, fit: _Laplace) -> np.ndarray:
    """dL/dtheta in the natural parameters (alpha, beta without the reference, s_p, s_s).

    Each rating's eta depends on one threshold pair, one system and one participant and
    stimulus, so every sum over ratings below is a bincount by threshold, system,
    participant or stimulus, never a (ratings x parameters) matrix."""
    _, _, (s_p, s_s) = _split(theta, data)
    lay, link = data.layout, fit.link
    q_p, q_s = lay.q
    u, v = fit.mode
    j, k = data.levels - 1, data.k
    count = j + (k - 1) + 2
    p_idx, s_idx = lay.participant, lay.stimulus
    # (rating, parameter) entries of d eta / d theta at a fixed mode and of the threshold
    # derivatives of (log pi, psi, D): each rating touches its upper and lower threshold,
    # its system's effect (none for the reference) and the two sds
    up, low, eff = data.category < j, data.category > 0, lay.system > 0
    rows = np.r_[np.flatnonzero(up), np.flatnonzero(low)]
    columns = np.r_[data.category[up], data.category[low] - 1]
    log_pi_a, psi_a, d_a = (np.r_[x[up], y[low]] for x, y in zip(link.upper, link.lower))
    effect_rows, effect_columns = np.flatnonzero(eff), j + lay.system[eff] - 1

    def per_level(factor: np.ndarray, levels: int, at_rows: np.ndarray, at_columns: np.ndarray,
                  weights: np.ndarray) -> np.ndarray:
        return np.bincount(factor[at_rows] * count + at_columns, weights, levels * count).reshape(levels, count)

    # the mode's change: H dw/dtheta = sum_i (dpsi_i - D_i deta_i) w_i + sum_i psi_i dw_i/ds
    changes = []
    for factor, levels, sd in ((p_idx, q_p, s_p), (s_idx, q_s, s_s)):
        c = (per_level(factor, levels, rows, columns, psi_a)
             + per_level(factor, levels, effect_rows, effect_columns, -link.d[eff]))
        c[:, -2] = -np.bincount(factor, link.d * u[p_idx], levels)
        c[:, -1] = -np.bincount(factor, link.d * v[s_idx], levels)
        changes.append(sd * c)
    psi_p, psi_s, _ = lay.sums(link.psi)
    changes[0][:, -2] += psi_p
    changes[1][:, -1] += psi_s
    du, dv = fit.blocks.solve(*changes)
    # tr(H^-1 dH/dtheta) = sum_i leverage_i dD_i/dtheta (+ Lambda's own change for the sds),
    # dD_i = dD_i/dalpha + D'_i (deta_i/dtheta + w_i' dw/dtheta)
    h_p, h_s, h_ps = fit.blocks.inverse_blocks()
    cross = h_ps[lay.pair]
    leverage = s_p**2 * h_p[p_idx] + s_s**2 * h_s[s_idx] + 2 * s_p * s_s * cross
    w = leverage * link.d_eta
    w_p, w_s, _ = lay.sums(w)
    trace = np.bincount(columns, leverage[rows] * d_a, count)
    trace += np.bincount(effect_columns, w[eff], count)
    trace[-2] += w_p @ u
    trace[-1] += w_s @ v
    trace += s_p * (w_p @ du) + s_s * (w_s @ dv)
    trace[-2] += 2 * link.d @ (s_p * h_p[p_idx] + s_s * cross)
    trace[-1] += 2 * link.d @ (s_s * h_s[s_idx] + s_p * cross)
    direct = np.bincount(columns, log_pi_a, count) + np.bincount(effect_columns, link.psi[eff], count)
    direct[-2], direct[-1] = psi_p @ u, psi_s @ v
    return direct - 0.5 * trace


def _to_natural(phi: np.ndarray, data: _Data) -> np.ndarray:
    j = data.levels - 1
    alpha = phi[0] + np.r_[0.0, np.cumsum(np.exp(phi[1:j]))]
    return np.r_[alpha, phi[j:]]


def _natural_gradient_to_phi(gradient: np.ndarray, phi: np.ndarray, data: _Data) -> np.ndarray:
    j = data.levels - 1
    out = gradient.copy()
    # alpha_m = phi_0 + sum_{l=1..m} exp(phi_l): d/dphi_0 sums all, d/dphi_l those from l on
    tail_sums = np.cumsum(gradient[:j][::-1])[::-1]
    out[0] = tail_sums[0]
    out[1:j] = np.exp(phi[1:j]) * tail_sums[1:j]
    return out


@dataclass(frozen=True)
class OrdinalFit:
    """One cell's fit: categories, systems (reference first), thresholds, system effects
    (the reference's 0 first), their covariance (alpha then beta), random-effect sds."""

    categories: list
    systems: list[str]
    thresholds: np.ndarray
    effects: np.ndarray
    covariance: np.ndarray
    participant_sd: float
    stimulus_sd: float
    log_likelihood: float
    converged: bool


def _start(data: _Data) -> np.ndarray:
    shares = np.bincount(data.category, minlength=data.levels).cumsum()[:-1] / len(data.category)
    alpha = np.log(shares / (1 - shares))
    phi_alpha = np.r_[alpha[0], np.log(np.maximum(np.diff(alpha), 1e-3))]
    return np.r_[phi_alpha, np.zeros(data.k - 1), [0.5 if free else 0.0 for free in data.free]]


def fit_ordinal(y: np.ndarray, layout: CrossedLayout,
                random: Sequence[str] = RANDOM_FACTORS) -> OrdinalFit:
    """Laplace fit of one cell's ratings (see the module docstring); ``random`` names the
    random factors kept (participant, stimulus; none gives the plain cumulative logit)."""
    categories, category = np.unique(y, return_inverse=True)
    if len(categories) < 2:
        raise AnalysisInputError("every rating has the same value; a cumulative link model needs two or more")
    if layout.constant_within_systems(y):
        raise AnalysisInputError("every rating equals its system's mean, so each system's ratings are one "
                                 "value and the log-odds between systems are not finite")
    data = _Data(layout, category.astype(np.int64), len(categories),
                 tuple(name in random for name in RANDOM_FACTORS))
    memo = {}

    def evaluate(phi):
        theta = _to_natural(phi, data)
        fit = _laplace(theta, data, memo.get("mode"))
        memo["mode"] = fit.mode
        return -fit.value, -_natural_gradient_to_phi(_gradient(theta, data, fit), phi, data)

    j = data.levels - 1
    fixed = ([(-_MAX_LOGIT, _MAX_LOGIT)] + [(None, np.log(2 * _MAX_LOGIT))] * (j - 1)
             + [(-_MAX_LOGIT, _MAX_LOGIT)] * (data.k - 1))
    # the thresholds and effects without random effects first (no modes to find), then all
    start = _start(data)
    plain = optimize.minimize(evaluate, start, jac=True, method="L-BFGS-B",
                              bounds=fixed + [(0.0, 0.0)] * 2, options={"gtol": 1e-5})
    start[: j + data.k - 1] = plain.x[: j + data.k - 1]
    memo.clear()
    # each sd over both signs: bounded at 0, where L's derivative in it vanishes, the search
    # stops wherever it steps onto the bound (module docstring)
    found = optimize.minimize(evaluate, start, jac=True, method="L-BFGS-B",
                              bounds=fixed + [(-_MAX_SD, _MAX_SD) if free else (0.0, 0.0) for free in data.free],
                              options={"ftol": 1e-15, "gtol": 1e-7, "maxiter": 2000})
    theta = _to_natural(found.x, data)
    if np.abs(theta[: j + data.k - 1]).max() >= _MAX_LOGIT * (1 - 1e-6):
        raise AnalysisInputError(
            "the ratings separate the systems (a fit matches them only with some values' probabilities at 0 "
            "for some systems, as when each system's ratings keep to values of their own), so log-odds "
            "grow without bound and have no finite estimate; the linear mixed model and the rank-based "
            "tests still apply")
    theta[-2:] = np.abs(theta[-2:])
    for index in (-2, -1):  # an sd the optimiser left a hair above zero belongs at zero
        at_zero = theta.copy()
        at_zero[index] = 0.0
        if 0 < theta[index] < _HAIR and _laplace(at_zero, data, memo.get("mode")).value >= -found.fun - 1e-9:
            theta = at_zero
    covariance = _covariance(theta, data, _laplace(theta, data, memo.get("mode")).mode)
    alpha, beta, (s_p, s_s) = _split(theta, data)
    return OrdinalFit(list(categories), layout.systems, alpha, beta, covariance, float(s_p), float(s_s),
                      _laplace(theta, data).value, bool(found.success))


def _covariance(theta: np.ndarray, data: _Data, mode: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Inverse of -L's Hessian by forward differences of the exact gradient, over the
    thresholds, the effects and the sds off their bound (the random effects' modes
    starting from ``mode``); returned for (alpha, beta)."""
    j, k = data.levels - 1, data.k
    free = list(range(j + k - 1)) + [j + k - 1 + i for i in range(2) if theta[j + k - 1 + i] > 0]
    at_optimum = _gradient(theta, data, _laplace(theta, data, mode))
    hessian = np.zeros((len(free), len(free)))
    for column, index in enumerate(free):
        step = 1e-6 * max(1.0, abs(theta[index]))
        moved = theta.copy()
        moved[index] += step
        hessian[:, column] = -(_gradient(moved, data, _laplace(moved, data, mode)) - at_optimum)[free] / step
    hessian = (hessian + hessian.T) / 2
    return np.linalg.inv(hessian)[: j + k - 1, : j + k - 1]


@dataclass
class OrdinalModelTables:
    """The cumulative link mixed model of every cell as tidy tables."""

    thresholds: pd.DataFrame
    effects: pd.DataFrame
    random_effects: pd.DataFrame
    notes: list[str] = field(default_factory=list)


def ordinal_mixed_model(data: pd.DataFrame, reference: str | None = None, dv: str = "value",
                        between: str = "system", participant: str = "participant",
                        stimulus: str = "stimulus", groupby: Sequence[str] = CELL,
                        alpha: float = 0.05, confidence: float = 0.95) -> OrdinalModelTables:
    """Fit ``ordered(dv) ~ between + (1 | participant) + (1 | stimulus)`` per cell.

    ``thresholds``: *groupby, threshold ("1|2", ...), estimate, se.
    ``effects``: *groupby, system, reference, difference (log-odds of a higher rating than
    the reference), se, ci_low, ci_high, z, p, p_holm, reject, odds_ratio.
    ``random_effects``: *groupby, component, levels, sd, at_boundary, log_likelihood
    (Laplace), converged.
    """
    thresholds, effects, random_effects, notes = [], [], [], []
    for key, frame in iter_cells(data, groupby):
        where = " · ".join(map(str, key.values())) or "all ratings"
        chosen = reference if reference in set(frame[between]) else None
        layout = crossed_layout(frame, chosen, between, participant, stimulus)
        try:
            with one_blas_thread():
                fit = fit_ordinal(frame[dv].to_numpy(), layout)
        except (AnalysisInputError, np.linalg.LinAlgError) as exc:
            notes.append(f"No cumulative link mixed model for {where}: {exc}.")
            continue
        j = len(fit.thresholds)
        se = np.sqrt(np.diag(fit.covariance))
        names = [f"{a}|{b}" for a, b in zip(fit.categories[:-1], fit.categories[1:])]
        thresholds.append(pd.DataFrame({**key, "threshold": names, "estimate": fit.thresholds, "se": se[:j]}))
        effect_covariance = np.zeros((len(fit.systems), len(fit.systems)))
        effect_covariance[1:, 1:] = fit.covariance[j:, j:]
        table = contrasts_against_reference(fit.effects, effect_covariance, fit.systems, alpha,
                                            confidence, effects=True).assign(**key)
        effects.append(table.assign(odds_ratio=np.exp(table["difference"])))
        random_effects.append(pd.DataFrame({
            **key, "component": [participant, stimulus], "levels": list(layout.q),
            "sd": [fit.participant_sd, fit.stimulus_sd],
            "at_boundary": [fit.participant_sd == 0, fit.stimulus_sd == 0],
            "log_likelihood": fit.log_likelihood, "converged": fit.converged}))
        if not fit.converged:
            notes.append(f"Cumulative link mixed model, {where}: the optimiser stopped before "
                         "converging; treat its estimates with care.")
    joined = [pd.concat(t, ignore_index=True) if t else pd.DataFrame()
              for t in (thresholds, effects, random_effects)]
    if len(joined[1]):
        joined[1] = joined[1][[*groupby, "system", "reference", "difference", "se", "ci_low", "ci_high",
                               "z", "p", "p_holm", "reject", "odds_ratio"]]
    return OrdinalModelTables(*joined, notes)
