"""Rotations in torch, differentiable: the counterparts of ``generation.motion.rotations``'
numpy functions that the models need, with the same names and the same conventions.

Quaternions are (w, x, y, z); q and −q are the same rotation. ``gram_schmidt`` turns a
network's 6-D output into a rotation matrix, ``normalize_quaternion`` its 4-D output
into a unit quaternion, and ``expmap_to_quat`` its rotation vector into one.
"""

from __future__ import annotations

import torch


def normalize_quaternion(q: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Quaternions (..., 4) scaled to unit length (a zero vector stays near zero, not NaN)."""
    return q / q.norm(dim=-1, keepdim=True).clamp_min(eps)


def gram_schmidt(x: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) from 6-D vectors (..., 6), the first two columns before
    orthonormalisation; the third column is their cross product, so det = +1."""
    a1, a2 = x[..., :3], x[..., 3:]
    b1 = a1 / a1.norm(dim=-1, keepdim=True).clamp_min(eps)
    b2 = a2 - (b1 * a2).sum(-1, keepdim=True) * b1
    b2 = b2 / b2.norm(dim=-1, keepdim=True).clamp_min(eps)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """Unit quaternions (..., 4), w first, to rotation matrices (..., 3, 3)."""
    w, x, y, z = q.unbind(-1)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)


def matrix_to_quat(r: torch.Tensor) -> torch.Tensor:
    """Rotation matrices (..., 3, 3) to unit quaternions (..., 4), w first.

    Each of the four components can be recovered from the diagonal as
    2|q_i| = sqrt(1 ± r00 ± r11 ± r22); the largest is the best conditioned, and the
    other three follow from the off-diagonal sums and differences divided by it.
    """
    r00, r11, r22 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    magnitudes = torch.stack([1 + r00 + r11 + r22, 1 + r00 - r11 - r22, 1 - r00 + r11 - r22, 1 - r00 - r11 + r22], -1)
    d21, d02, d10 = r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]
    s10, s02, s21 = r[..., 1, 0] + r[..., 0, 1], r[..., 0, 2] + r[..., 2, 0], r[..., 2, 1] + r[..., 1, 2]
    # Row i: 4 q_i q, i.e. the quaternion scaled by 4 q_i, for i = w, x, y, z.
    candidates = torch.stack([
        torch.stack([magnitudes[..., 0], d21, d02, d10], -1),
        torch.stack([d21, magnitudes[..., 1], s10, s02], -1),
        torch.stack([d02, s10, magnitudes[..., 2], s21], -1),
        torch.stack([d10, s02, s21, magnitudes[..., 3]], -1),
    ], -2)
    best = magnitudes.argmax(-1)
    chosen = candidates.gather(-2, best[..., None, None].expand(*best.shape, 1, 4)).squeeze(-2)
    return normalize_quaternion(chosen)


def expmap_to_quat(v: torch.Tensor) -> torch.Tensor:
    """Unit quaternions (..., 4) of rotation vectors (..., 3): the angle ‖v‖ about v/‖v‖.
    Every vector is a valid rotation, so axis-angle outputs need no normalisation."""
    angle = (v * v).sum(-1, keepdim=True).clamp_min(1e-12).sqrt()
    half = 0.5 * angle
    # sin(θ/2)/θ by its series near 0, where the quotient loses precision.
    scale = torch.where(angle < 1e-3, 0.5 - angle**2 / 48, torch.sin(half) / angle)
    return torch.cat([torch.cos(half), v * scale], dim=-1)


def align_quaternions(features: torch.Tensor, reference: torch.Tensor, root_dims: int) -> torch.Tensor:
    """Features (..., root_dims + 4J) with every joint's quaternion flipped onto the side
    of its ``reference`` (J, 4). q and −q are one rotation; networks and squared errors
    should see one sign."""
    root, quats = features[..., :root_dims], features[..., root_dims:].unflatten(-1, (-1, 4))
    flip = (quats * reference).sum(-1, keepdim=True) < 0
    return torch.cat([root, torch.where(flip, -quats, quats).flatten(-2)], -1)

