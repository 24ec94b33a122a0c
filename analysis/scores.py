"""Inception Score and Frechet distance of generated motion (HVRNN Sec. 5.2, Eq. 27-29).

Both read the outputs of a motion classifier trained on natural data (that classifier
lives in `generation`): class probabilities p(y|x) for IS, penultimate-layer activations
for FID. Here they are plain arrays.

    IS  = exp( E_x KL( p(y|x) || p(y) ) ),  p(y) = E_x p(y|x)
    FID = |mu_r - mu_g|^2 + Tr( S_r + S_g - 2 (S_r S_g)^(1/2) )
"""

from __future__ import annotations

import numpy as np
from scipy import linalg

from analysis.errors import AnalysisInputError

_IMAGINARY_TOLERANCE = 1e-3


def inception_score(probabilities: np.ndarray) -> float:
    """IS from class probabilities (clips, classes); each row must sum to 1."""
    p = np.asarray(probabilities, dtype=np.float64)
    if p.ndim != 2 or len(p) == 0:
        raise AnalysisInputError(f"class probabilities must be (clips, classes), got {p.shape}")
    if (p < 0).any() or not np.allclose(p.sum(axis=1), 1.0, atol=1e-4):
        raise AnalysisInputError("class probabilities must be non-negative and sum to 1 per clip")
    marginal = p.mean(axis=0)
    # 0 * log 0 = 0: classes a clip gives no probability add nothing to its KL
    with np.errstate(divide="ignore", invalid="ignore"):
        kl = np.where(p > 0, p * (np.log(p) - np.log(marginal)), 0.0).sum(axis=1)
    return float(np.exp(kl.mean()))


def frechet_distance(real: np.ndarray, generated: np.ndarray) -> float:
    """FID between two sets of activations (clips, features) via Gaussian fits.

    sqrtm of a product of covariances can pick up a tiny imaginary part from rounding;
    it is dropped when negligible and reported as an error otherwise.
    """
    real, generated = (np.asarray(a, dtype=np.float64) for a in (real, generated))
    if real.ndim != 2 or generated.ndim != 2 or real.shape[1] != generated.shape[1]:
        raise AnalysisInputError(
            f"activations must be (clips, features) with equal features, got {real.shape} "
            f"and {generated.shape}"
        )
    if min(len(real), len(generated)) < 2:
        raise AnalysisInputError("FID needs at least two clips in each set")
    mu_r, mu_g = real.mean(axis=0), generated.mean(axis=0)
    cov_r = np.atleast_2d(np.cov(real, rowvar=False))
    cov_g = np.atleast_2d(np.cov(generated, rowvar=False))
    root = linalg.sqrtm(cov_r @ cov_g)
    if np.iscomplexobj(root):
        if np.abs(root.imag).max() > _IMAGINARY_TOLERANCE * max(1.0, np.abs(root.real).max()):
            raise AnalysisInputError("covariance product has no real square root; FID undefined")
        root = root.real
    return float(((mu_r - mu_g) ** 2).sum() + np.trace(cov_r + cov_g - 2.0 * root))
