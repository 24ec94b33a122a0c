"""ERD (Fragkiadaki et al., 2015), an attribute-controlled baseline of Ghorbani et al.'s Table 2.

An encoder MLP, a two-layer LSTM and a decoder MLP (paper sizes 500-500, 2 × 1000 and
500-100) step through the sequence as ``recurrent.RecurrentBaseline`` describes. It
learns by squared error on the features (standardised root values, unit quaternions).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from .parts.layers import mlp
from .recurrent import RecurrentBaseline, RecurrentConfig


@dataclass
class ERDConfig(RecurrentConfig):
    """Hyperparameters; the defaults are ERD's sizes (the ``paper`` preset)."""

    encoder: tuple[int, ...] = (500, 500)
    decoder: tuple[int, ...] = (500, 100)


class ERD(RecurrentBaseline):
    kind = "erd"
    Config = ERDConfig
    state_parts = 2

    def __init__(self, config: ERDConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.encoder = nn.Sequential(mlp([pose_dim + control_dim, *config.encoder]), nn.ReLU())
        self.recurrent = nn.LSTM(config.encoder[-1], config.hidden, config.layers, batch_first=True)
        self.decoder = mlp([config.hidden, *config.decoder, pose_dim])

    def run(self, inputs: torch.Tensor, codes: torch.Tensor, state: Any) -> tuple[torch.Tensor, Any]:
        h, state = self.recurrent(self.encoder(self.with_codes(inputs, codes)), state)
        return self.decoder(h), state

    def frame_error(self, predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return ((predicted - target) ** 2).mean(-1)


