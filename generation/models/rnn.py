"""MoGlow's RNN baseline (Henter et al. 2020, Sec. 4.3): one LSTM from control to pose.

A single unidirectional LSTM layer reads the control signal frame by frame and a linear
layer turns its state into that frame's pose. Trained to minimise the mean squared error
on standardised poses, it predicts the conditional mean pose: a deterministic regression
model, included to show the averaged, "floaty" motion that MoGlow's probabilistic
modelling avoids. Because the LSTM is causal, it can run in real time on a live control
stream, like MoGlow.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from .path import PathModel


@dataclass
class RNNConfig:
    hidden_size: int = 512  # LSTM units


class RNNBaseline(PathModel):
    """Control sequence → pose sequence through one causal LSTM layer and a linear output.

    The pose of frame t depends only on the control of frames ≤ t. The model is
    deterministic: ``generate`` ignores ``temperature`` and ``generator`` (there is no
    noise to scale or seed) and ``context`` (it never reads past poses).
    """

    kind = "rnn"
    per_row_seeds = True  # it draws nothing
    Config = RNNConfig
    context_frames = 0

    def __init__(self, config: RNNConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.lstm = nn.LSTM(control_dim, config.hidden_size, batch_first=True)
        self.output = nn.Linear(config.hidden_size, pose_dim)

    def forward(self, control: torch.Tensor) -> torch.Tensor:
        """Predicted poses (batch, frames, pose_dim) for control (batch, frames, control_dim)."""
        states, _ = self.lstm(control)
        return self.output(states)

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        mse = F.mse_loss(self(control), pose)
        return mse, {"mse": mse.item()}

    @torch.no_grad()
    def generate(
        self,
        control: torch.Tensor,
        context: torch.Tensor | None = None,
        temperature: float = 1.0,
        generator: torch.Generator | None = None,
        precision: str = "float32",
    ) -> torch.Tensor:
        """The predicted poses; the same for every temperature and seed (see the class)."""
        self.check_precision(precision)
        return self(control.to(self.output.weight))
