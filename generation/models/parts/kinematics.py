"""Forward kinematics in torch, differentiable, for losses on joint positions (QuaterNet)."""

from __future__ import annotations

import torch


def forward_kinematics(rotations: torch.Tensor, offsets: torch.Tensor, parents: list[int]) -> torch.Tensor:
    """Joint positions (..., J, 3) from local rotation matrices (..., J, 3, 3), rest
    offsets (J, 3) and parent indices (parents before children); the root's offset
    places the root, as in ``generation.motion.kinematics.forward_kinematics`` with
    every frame's translations equal to the offsets."""
    global_rotations: list[torch.Tensor] = []
    positions: list[torch.Tensor] = []
    for j, p in enumerate(parents):
        if p < 0:
            global_rotations.append(rotations[..., j, :, :])
            positions.append(offsets[j].expand(*rotations.shape[:-3], 3))
        else:
            global_rotations.append(global_rotations[p] @ rotations[..., j, :, :])
            positions.append(positions[p] + (global_rotations[p] @ offsets[j].unsqueeze(-1)).squeeze(-1))
    return torch.stack(positions, -2)
