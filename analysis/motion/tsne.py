"""Exact t-SNE (van der Maaten and Hinton, 2008) in numpy, for a few hundred points.

The HVRNN evaluation embeds classifier activations of real and generated sequences in
two dimensions (Ghorbani et al., Fig. 4). With a few hundred sequences the exact
O(n²) algorithm takes seconds, so no approximation (or extra dependency) is needed:

* affinities: a Gaussian around each point whose width gives the conditional
  distribution p(j|i) the requested perplexity (found by bisection on the precision),
  symmetrised as p_ij = (p(j|i) + p(i|j)) / 2n;
* embedding: Student-t similarities q_ij ∝ (1 + |y_i − y_j|²)⁻¹, gradient descent on
  KL(P‖Q) with momentum, per-parameter gains and early exaggeration; started from the
  first two principal components (scaled small), so the result is deterministic.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import AnalysisInputError


def conditional_affinities(x: np.ndarray, perplexity: float, tolerance: float = 1e-5, max_steps: int = 100) -> np.ndarray:
    """p(j|i) (n, n), each row with entropy log(perplexity), zero on the diagonal."""
    n = len(x)
    squared = np.square(x[:, None, :] - x[None, :, :]).sum(-1)
    target = np.log(perplexity)
    p = np.zeros((n, n))
    for i in range(n):
        d = np.delete(squared[i], i)
        d = d - d.min()  # shifting distances leaves the normalised row unchanged and avoids underflow
        low, high, beta = 0.0, np.inf, 1.0
        for _ in range(max_steps):
            w = np.exp(-d * beta)
            total = w.sum()
            row = w / total
            entropy = np.log(total) + beta * (d * row).sum()
            if abs(entropy - target) < tolerance:
                break
            if entropy > target:  # too flat: sharpen
                low, beta = beta, beta * 2 if high == np.inf else (beta + high) / 2
            else:
                high, beta = beta, (beta + low) / 2
        p[i, np.arange(n) != i] = row
    return p


def kl_divergence(p: np.ndarray, y: np.ndarray) -> float:
    """KL(P‖Q) of joint affinities P and the embedding's Student-t similarities Q."""
    q = _student_t(y)
    q = q / q.sum()
    mask = p > 0
    return float((p[mask] * np.log(p[mask] / np.maximum(q[mask], 1e-300))).sum())


def _student_t(y: np.ndarray) -> np.ndarray:
    num = 1.0 / (1.0 + np.square(y[:, None, :] - y[None, :, :]).sum(-1))
    np.fill_diagonal(num, 0.0)
    return num


def tsne(x: np.ndarray, perplexity: float = 30.0, iterations: int = 1000, learning_rate: float | None = None,
         exaggeration: float = 12.0, exaggeration_iterations: int = 250) -> np.ndarray:
    """A 2-D embedding (n, 2) of the rows of ``x`` (n, features)."""
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or len(x) < 4:
        raise AnalysisInputError(f"t-SNE needs at least 4 points as (points, features), got shape {x.shape}")
    if not np.isfinite(x).all():
        raise AnalysisInputError("t-SNE input contains NaN or infinity")
    n = len(x)
    if not 1.0 <= perplexity <= (n - 1) / 3:
        raise AnalysisInputError(f"perplexity must be between 1 and (points - 1) / 3 = {(n - 1) / 3:.1f}, got {perplexity}")
    p = conditional_affinities(x, perplexity)
    p = np.maximum((p + p.T) / (2 * n), 1e-12)
    if learning_rate is None:
        learning_rate = max(n / exaggeration / 4, 50.0)  # the "auto" rate of Belkina et al. (2019)

    centred = x - x.mean(0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    y = centred @ vt[:2].T
    y = y / np.std(y[:, 0]) * 1e-4 if np.std(y[:, 0]) > 0 else np.zeros((n, 2))
    velocity, gains = np.zeros_like(y), np.ones_like(y)
    for step in range(iterations):
        scale = exaggeration if step < exaggeration_iterations else 1.0
        num = _student_t(y)
        q = np.maximum(num / num.sum(), 1e-12)
        # dC/dy_i = 4 Σ_j (p_ij − q_ij)(1 + |y_i − y_j|²)⁻¹ (y_i − y_j)
        w = (scale * p - q) * num
        gradient = 4.0 * (np.diag(w.sum(1)) - w) @ y
        momentum = 0.5 if step < exaggeration_iterations else 0.8
        same_sign = np.sign(gradient) == np.sign(velocity)
        gains = np.maximum(np.where(same_sign, gains * 0.8, gains + 0.2), 0.01)
        velocity = momentum * velocity - learning_rate * gains * gradient
        y = y + velocity
        y = y - y.mean(0)
    return y
