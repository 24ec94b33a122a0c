"""How the auxiliary networks (classifiers, denoiser) see angle features.

Raw angle features (six root values, then joint quaternions) are prepared in two
steps: each quaternion is flipped into the hemisphere of the training average (q and
−q are one rotation; clips, and generated sequences, need not agree on the sign), then
every dimension is standardised with the statistics of the sign-aligned training
frames. The statistics are buffers, so they travel with the network's weights.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..models.parts.rotations import align_quaternions
from .data import ROOT_DIMS, SequenceSet

# Some quaternion components barely move in the data; dividing by their tiny spread
# would turn a few degrees of another take's posture into hundreds of standard
# deviations, so their spread is floored (0.05 is about 6 degrees of rotation).
MIN_QUATERNION_STD = 0.05


class InputNormalizer(nn.Module):
    """``forward``: raw features (..., dims) to sign-aligned standardised ones; ``invert`` back."""

    def __init__(self, feature_dim: int) -> None:
        super().__init__()
        if feature_dim <= ROOT_DIMS or (feature_dim - ROOT_DIMS) % 4:
            raise ValueError(f"feature_dim {feature_dim} is not {ROOT_DIMS} root values plus quaternions")
        self.register_buffer("mean", torch.zeros(feature_dim))
        self.register_buffer("std", torch.ones(feature_dim))
        self.register_buffer("reference", torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat((feature_dim - ROOT_DIMS) // 4, 1))

    def align(self, features: torch.Tensor) -> torch.Tensor:
        """The same rotations, each quaternion on the reference's side."""
        return align_quaternions(features, self.reference, ROOT_DIMS)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return (self.align(features) - self.mean) / self.std

    def invert(self, normalized: torch.Tensor) -> torch.Tensor:
        return normalized * self.std + self.mean

    @torch.no_grad()
    def fit(self, sequences: SequenceSet, reference: np.ndarray) -> None:
        """Set the sign reference, then the mean and (floored) spread of the aligned real frames."""
        features, mask, _, _ = sequences.tensors()
        self.reference.copy_(torch.as_tensor(reference, dtype=torch.float32))
        aligned = self.align(features)[mask]
        floor = torch.full_like(self.std, MIN_QUATERNION_STD)
        floor[:ROOT_DIMS] = 1e-6
        self.mean.copy_(aligned.mean(0))
        self.std.copy_(torch.maximum(aligned.std(0), floor))
