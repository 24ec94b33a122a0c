"""The studentized range distribution by fixed quadrature, vectorised over many q at once.

Tukey's HSD needs P(Q > q) for every pair of systems. scipy.stats.studentized_range
integrates adaptively point by point, about 20 ms per value at the degrees of freedom of
a large study (tens of thousands of ratings), which alone would take seconds per table.
Here both integrals are done on fixed grids in one array expression:

    P(Q > q) = E_s[ P(R > q s) ],   s = sqrt(chi2_df / df)
    P(R > w) = k * Int phi(z) (Phi(z)^(k-1) - (Phi(z) - Phi(z - w))^(k-1)) dz

with R the range of k standard normals. The inner integral uses the trapezoid rule on
a fine z grid, the outer one the trapezoid rule in t = log s over the span where the
density of t is within e^-30 of its mode (both integrands are smooth and decay fast, so
the trapezoid rule converges spectrally). Agreement with scipy is better than 1e-10
(pinned down in tests/test_analysis_stats.py).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import optimize, special

_Z = np.linspace(-9.0, 9.0, 241)
_DZ = _Z[1] - _Z[0]
_PHI = np.exp(-0.5 * _Z**2) / np.sqrt(2.0 * np.pi)
_CDF = special.ndtr(_Z)
_MIN_SCALE_NODES = 64
_MAX_SCALE_STEP = 0.05  # in log s; only very small df (wide spans) need the extra nodes
_LOG_DENSITY_SPAN = 30.0


def _range_sf(w: np.ndarray, k: int) -> np.ndarray:
    """P(R > w) for the range R of k independent standard normals."""
    inner = _CDF - special.ndtr(_Z - w[..., None])
    integrand = _PHI * (_CDF ** (k - 1) - inner ** (k - 1))
    return np.clip(k * integrand.sum(axis=-1) * _DZ, 0.0, 1.0)


@lru_cache(maxsize=64)
def _scale_nodes(df: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes s and weights for E_s[.] with s = sqrt(chi2_df / df)."""
    if np.isinf(df):
        return np.ones(1), np.ones(1)

    def log_density(t):  # of t = log s, up to a constant; its mode is t = 0
        return df * t - 0.5 * df * np.expm1(2.0 * t)

    lo = optimize.brentq(lambda t: log_density(t) + _LOG_DENSITY_SPAN, -1e3, 0.0)
    hi = optimize.brentq(lambda t: log_density(t) + _LOG_DENSITY_SPAN, 0.0, 50.0)
    t = np.linspace(lo, hi, max(_MIN_SCALE_NODES, int((hi - lo) / _MAX_SCALE_STEP)))
    weights = np.exp(log_density(t))
    return np.exp(t), weights / weights.sum()


def studentized_range_sf(q: np.ndarray, k: int, df: float) -> np.ndarray:
    """P(Q > q) for the studentized range of k means with df error degrees of freedom."""
    q = np.asarray(q, dtype=np.float64)
    s, weights = _scale_nodes(float(df))
    flat = q.reshape(-1)
    sf = _range_sf(flat[:, None] * s[None, :], k) @ weights
    return np.clip(sf, 0.0, 1.0).reshape(q.shape)


def studentized_range_ppf(p: float, k: int, df: float) -> float:
    """The q with P(Q <= q) = p (the critical value of Tukey's HSD at level 1 - p)."""
    return optimize.brentq(lambda q: studentized_range_sf(np.array([q]), k, df)[0] - (1 - p),
                           1e-6, 100.0, xtol=1e-10)
