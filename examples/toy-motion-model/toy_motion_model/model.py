"""A toy path-controlled model: each frame's pose from the control of the last few frames.

An MLP reads the control of frames t-window+1..t and outputs the mean of a Gaussian over
the pose of frame t, with one learned standard deviation per pose feature. Trained by the
Gaussian negative log-likelihood; sampling draws from it (``temperature`` scales the
standard deviation). Not a good model: an example of the interface a plugin implements.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from generation.models.parts.noise import RowGenerators, normal
from generation.models.path import PathModel


@dataclass
class ToyConfig:
    window: int = 5  # frames of control each pose sees
    hidden: int = 256


class ToyPathModel(PathModel):
    kind = "toy"
    Config = ToyConfig
    context_frames = 0
    per_row_seeds = True  # its one draw goes through noise.normal

    def __init__(self, config: ToyConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.net = nn.Sequential(nn.Linear(config.window * control_dim, config.hidden), nn.ReLU(),
                                 nn.Linear(config.hidden, pose_dim))
        self.log_std = nn.Parameter(torch.full((pose_dim,), -1.0))

    def _mean(self, control: torch.Tensor) -> torch.Tensor:
        # Pad the start by repeating the first frame, so frame t sees a full window.
        padded = torch.cat([control[:, :1].expand(-1, self.config.window - 1, -1), control], dim=1)
        windows = padded.unfold(1, self.config.window, 1)  # (batch, frames, control_dim, window)
        return self.net(windows.transpose(2, 3).flatten(2))

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        mean = self._mean(control)
        nll = F.gaussian_nll_loss(mean, pose, torch.exp(2 * self.log_std).expand_as(mean))
        return nll, {"nll": nll.item()}

    @torch.no_grad()
    def generate(self, control: torch.Tensor, context: torch.Tensor | None = None, temperature: float = 1.0,
                 generator: torch.Generator | RowGenerators | None = None, precision: str = "float32") -> torch.Tensor:
        self.check_precision(precision)
        mean = self._mean(control.to(self.log_std))
        noise = normal(mean.shape, generator, device=mean.device, dtype=mean.dtype)
        return mean + temperature * torch.exp(self.log_std) * noise
