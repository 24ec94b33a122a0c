"""Small building blocks that several models share."""

from __future__ import annotations

import torch
from torch import nn


def mlp(sizes: list[int]) -> nn.Sequential:
    """Linear layers with ReLU between them (none after the last)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers += [nn.Linear(a, b)] + ([nn.ReLU()] if i < len(sizes) - 2 else [])
    return nn.Sequential(*layers)


def random_crop(pose: torch.Tensor, mask: torch.Tensor, frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    """A random stretch of ``frames`` frames of each sequence, within its real frames
    where it is long enough (else its start), with the mask cut alike."""
    lengths = mask.sum(1)
    start = (torch.rand(len(pose), device=pose.device) * (lengths - frames + 1).clamp_min(1)).long()
    index = start[:, None] + torch.arange(frames, device=pose.device)
    pose = pose.gather(1, index[..., None].expand(-1, -1, pose.shape[-1]))
    return pose, mask.gather(1, index)
