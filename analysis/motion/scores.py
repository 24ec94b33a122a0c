"""Inception Score and Frechet distance of generated motion (HVRNN Sec. 5.2, Eq. 27-29).

Both read the outputs of a motion classifier trained on natural data (that classifier
lives in `generation`): class probabilities p(y|x) for IS, penultimate-layer activations
for FID. Here they are plain arrays.

    IS  = exp( E_x KL( p(y|x) || p(y) ) ),  p(y) = E_x p(y|x)
    FID = |mu_r - mu_g|^2 + Tr( S_r + S_g - 2 (S_r S_g)^(1/2) )   (`analysis.motion.frechet`)
"""

from __future__ import annotations

import numpy as np

from analysis.errors import AnalysisInputError
from analysis.motion.frechet import frechet_distance  # noqa: F401 (FID of activations: (clips, features) per set)


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

