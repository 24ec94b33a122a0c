"""The Fréchet distance of pose features: how far a set of motion frames lies from the
natural motion's, as FGD (Yoon et al. 2020) and FID measure it.

Each set of frames (rows) of features (columns) is summarised by its mean ``mu`` and
covariance ``S``; the distance of two Gaussians is

    ||mu1 - mu2||^2 + Tr(S1 + S2 - 2 (S1 S2)^(1/2)).

``(S1 S2)^(1/2)`` has the eigenvalues of the symmetric ``S1^(1/2) S2 S1^(1/2)``'s square
root, so its trace is taken from that matrix's eigenvalues (both covariances are positive
semi-definite): no complex square root and no rounding into a negative distance, where the
general matrix square root FID implementations use (scipy.linalg.sqrtm) needs both guarded.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import AnalysisInputError


def _psd_sqrt(matrix: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh((matrix + matrix.T) / 2)
    return (vectors * np.sqrt(np.clip(values, 0.0, None))) @ vectors.T


def gaussian_frechet(mu1: np.ndarray, cov1: np.ndarray, mu2: np.ndarray, cov2: np.ndarray) -> float:
    """The Fréchet distance of two Gaussians given by means and covariances."""
    root1 = _psd_sqrt(cov1)
    cross = np.linalg.eigvalsh(root1 @ cov2 @ root1)
    trace = np.trace(cov1) + np.trace(cov2) - 2.0 * np.sqrt(np.clip(cross, 0.0, None)).sum()
    return float(max(np.sum((mu1 - mu2) ** 2) + trace, 0.0))


def frechet_distance(features: np.ndarray, reference: np.ndarray) -> float:
    """The Fréchet distance of the Gaussians fitted to two (samples, features) arrays: frames
    of pose features here, a classifier's activations of clips for FID (`analysis.motion.scores`)."""
    features, reference = (np.asarray(a, dtype=np.float64) for a in (features, reference))
    if features.ndim != 2 or reference.ndim != 2 or features.shape[1] != reference.shape[1]:
        raise AnalysisInputError(f"Fréchet distance: both sets must be (samples, features) with equal features, "
                                 f"got {features.shape} and {reference.shape}")
    if len(features) < 2 or len(reference) < 2:
        raise AnalysisInputError("Fréchet distance: a covariance needs two or more samples in each set")
    return gaussian_frechet(features.mean(axis=0), np.atleast_2d(np.cov(features, rowvar=False)),
                            reference.mean(axis=0), np.atleast_2d(np.cov(reference, rowvar=False)))


def pose_features(clip: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Per frame, every joint's position relative to the root (the joint without a parent),
    flattened: (frames, 3 joints). Where the figure stands is left out, so the features
    compare poses (and facings), not where the clips went."""
    root = int(np.flatnonzero(np.asarray(parents) < 0)[0])
    return (clip - clip[:, [root]]).reshape(len(clip), -1)
