"""Rotation distances and the loss terms of HVRNN (Ghorbani et al., Sec. 3.5).

Quaternions are (w, x, y, z), as in ``generation.motion.rotations``; q and −q are the
same rotation, so every quaternion distance below is invariant to either sign:

    d1(q1, q2) = min(‖q1 − q2‖, ‖q1 + q2‖)
    d2(q1, q2) = 1 − |⟨q1, q2⟩|
    d3(q1, q2) = arccos |⟨q1, q2⟩|            (half the angle of the relative rotation)

and for rotation matrices the geodesic distance on SO(3), the angle of R1ᵀR2:

    d(R1, R2) = ‖log(R1ᵀ R2)‖_F / √2 = arccos((tr(R1ᵀ R2) − 1) / 2).

The hierarchical reconstruction loss weighs joint k's distance by α_k, the longest
path (in bones) from k to the end effectors below it: an error near the root moves
everything below it, an error at a wrist moves only the hand.
"""

from __future__ import annotations

import numpy as np
import torch

QUATERNION_DISTANCES = ("d1", "d2", "d3")

# arccos has an infinite slope at 1 (zero distance); keeping its argument below 1 by
# this margin keeps d3's gradient finite and changes distances by under 1e-3 rad.
_ACOS_MARGIN = 1e-7


def quaternion_distance(q1: torch.Tensor, q2: torch.Tensor, kind: str = "d2") -> torch.Tensor:
    """d1, d2 or d3 between unit quaternions (..., 4); the result has shape (...)."""
    if kind == "d1":
        return torch.minimum((q1 - q2).norm(dim=-1), (q1 + q2).norm(dim=-1))
    dot = (q1 * q2).sum(-1).abs()
    if kind == "d2":
        return 1.0 - dot
    if kind == "d3":
        return torch.acos(dot.clamp(max=1.0 - _ACOS_MARGIN))
    raise ValueError(f"unknown quaternion distance {kind!r}; use one of {QUATERNION_DISTANCES}")


def rotation_matrix_distance(r1: torch.Tensor, r2: torch.Tensor) -> torch.Tensor:
    """The angle (radians) of the rotation between matrices (..., 3, 3): the SO(3) log distance."""
    trace = (r1 * r2).sum((-2, -1))  # tr(R1ᵀ R2) without forming the product
    cosine = ((trace - 1.0) / 2.0).clamp(-1.0 + _ACOS_MARGIN, 1.0 - _ACOS_MARGIN)
    return torch.acos(cosine)


def quaternion_validity(raw: torch.Tensor) -> torch.Tensor:
    """(‖q‖ − 1)² of unnormalised network outputs (..., 4): zero for valid rotations."""
    return (raw.norm(dim=-1) - 1.0) ** 2


def matrix_validity(raw: torch.Tensor) -> torch.Tensor:
    """How far 6-D outputs (..., 6) are from two orthonormal columns: Σ of squared
    departures of their lengths from 1 and of their dot product from 0."""
    a1, a2 = raw[..., :3], raw[..., 3:]
    return (a1.norm(dim=-1) - 1.0) ** 2 + (a2.norm(dim=-1) - 1.0) ** 2 + (a1 * a2).sum(-1) ** 2


def joint_weights(parents: np.ndarray | list[int]) -> np.ndarray:
    """α_k of every joint: the most bones on a path from joint k down to an end effector.

    A leaf joint drives the bone to its end effector (its BVH End Site), so α = 1 there,
    and a joint's α is one more than the largest α among its children. Parents must
    come before children (as in ``Skeleton``).
    """
    parents = np.asarray(parents, dtype=np.int64)
    alpha = np.ones(len(parents))
    for j in range(len(parents) - 1, 0, -1):  # children before parents
        p = parents[j]
        if p >= 0:
            alpha[p] = max(alpha[p], alpha[j] + 1.0)
    return alpha


def hierarchical_distance(
    predicted: torch.Tensor, target: torch.Tensor, alpha: torch.Tensor, kind: str = "d2"
) -> torch.Tensor:
    """Σ_k α_k d(predicted_k, target_k) per frame, for unit quaternions (..., joints, 4)
    (kind d1/d2/d3) or rotation matrices (..., joints, 3, 3) (kind "so3")."""
    if kind == "so3":
        distances = rotation_matrix_distance(predicted, target)
    else:
        distances = quaternion_distance(predicted, target, kind)
    return (distances * alpha).sum(-1)


def masked_mean(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The mean of ``values`` (batch, frames) over the frames where ``mask`` is true."""
    mask = mask.to(values.dtype)
    return (values * mask).sum() / mask.sum().clamp_min(1.0)


def kl_diagonal_gaussians(
    mean_q: torch.Tensor, logvar_q: torch.Tensor, mean_p: torch.Tensor, logvar_p: torch.Tensor
) -> torch.Tensor:
    """KL(N(mean_q, exp logvar_q) ‖ N(mean_p, exp logvar_p)), summed over the last dimension."""
    return 0.5 * (
        logvar_p - logvar_q + (logvar_q.exp() + (mean_q - mean_p) ** 2) / logvar_p.exp() - 1.0
    ).sum(-1)

