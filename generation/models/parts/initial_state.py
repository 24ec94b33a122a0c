"""The learned initial state of the label-controlled recurrent models (HVRNN, ERD, QuaterNet).

Each (action, style) pair has a diagonal Gaussian over the recurrent state; a sequence
starts from a draw of its pair's Gaussian, which at generation is the models' only
source of variety besides HVRNN's latents. Training draws it too (reparameterised) and
adds ``weight`` × KL(N(μ, σ²) ‖ N(0, I)): without that term the reconstruction loss alone
shrinks σ to nothing and the initial state becomes a constant.
"""

from __future__ import annotations

import torch
from torch import nn

from .losses import kl_diagonal_gaussians
from .noise import RowGenerators, normal


class LabelledInitialState(nn.Module):
    """A Gaussian over a ``size``-D state for each of ``pairs`` label pairs."""

    def __init__(self, pairs: int, size: int, initial_logvar: float = 0.0) -> None:
        super().__init__()
        self.mean = nn.Parameter(torch.zeros(pairs, size))
        self.logvar = nn.Parameter(torch.full((pairs, size), initial_logvar))

    def forward(self, pair: torch.Tensor, temperature: float = 1.0,
                generator: torch.Generator | RowGenerators | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """A state (batch, size) for each pair index, with σ scaled by ``temperature``, and
        each Gaussian's KL from N(0, I) (batch,)."""
        mean, logvar = self.mean[pair], self.logvar[pair]
        noise = normal(mean.shape, generator, device=mean.device, dtype=mean.dtype)
        kl = kl_diagonal_gaussians(mean, logvar, torch.zeros_like(mean), torch.zeros_like(logvar))
        return mean + temperature * (0.5 * logvar).exp() * noise, kl
