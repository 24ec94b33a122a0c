"""MoGlow: probabilistic, controllable motion synthesis with normalising flows.

Henter, Alexanderson and Beskow, "MoGlow: Probabilistic and controllable motion
synthesis using normalising flows", ACM TOG 39(6), 2020.

Each pose x_t is the image of Gaussian noise z_t under an invertible flow whose
coupling networks see the conditioning information

    c_t = (x_{t-τ}, ..., x_{t-1}, s_{t-τ}, ..., s_t)          (poses, then control)

and, through their LSTM state, everything before it. The likelihood of a sequence is
(Eq. 10)

    log p(x_τ..x_{T-1}) = Σ_t [ log N(z_t; 0, I) + Σ_n log|det ∂f_n/∂(input)| ]

and sampling draws z_t ~ N(0, θ² I) and inverts the flow frame by frame. During
training whole past poses in c_t are zeroed at random ("data dropout"), which
forces the model to listen to the control.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from .path import PathModel
from .parts.flows import Flow, glow_step
from .parts.noise import RowGenerators, normal
from .parts.precision import PRECISIONS, available_precisions


@dataclass
class MoGlowConfig:
    """Hyperparameters; the defaults are the paper's locomotion model (the ``paper`` preset)."""

    steps: int = 16  # N, steps of flow
    tau: int = 10  # τ, past poses (and τ+1 control frames) in the conditioning
    lstm_hidden: int = 512
    lstm_layers: int = 2
    dropout: float = 0.95  # probability of zeroing each past pose in the conditioning (training only)
    # The coupling's scale is sigmoid(h + scale_offset) + scale_floor (flows.AffineCoupling);
    # checkpoints imported from the authors' code use 2 and 1e-6.
    scale_offset: float = 0.0
    scale_floor: float = 0.05


class MoGlow(PathModel):
    kind = "moglow"
    Config = MoGlowConfig
    precisions = PRECISIONS
    per_row_seeds = True

    def __init__(self, config: MoGlowConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        for name in ("steps", "tau", "lstm_hidden", "lstm_layers"):
            if getattr(config, name) < 1:
                raise ValueError(f"{name} must be at least 1, not {getattr(config, name)}")
        if not 0.0 <= config.dropout <= 1.0:
            raise ValueError(f"dropout must lie in [0, 1], not {config.dropout}")
        if not config.scale_floor > 0.0:
            raise ValueError(f"scale_floor must be positive (the inverse divides by the scale), not {config.scale_floor}")
        self.context_frames = config.tau
        self.conditioning_dim = config.tau * pose_dim + (config.tau + 1) * control_dim
        self.flow = Flow([
            transform
            for _ in range(config.steps)
            for transform in glow_step(pose_dim, self.conditioning_dim, config.lstm_hidden, config.lstm_layers,
                                       config.scale_offset, config.scale_floor)
        ])

    def conditioning(self, pose: torch.Tensor, control: torch.Tensor) -> torch.Tensor:
        """c_t for t = τ..T-1: (batch, T-τ, τ·pose_dim + (τ+1)·control_dim).

        In training mode each past pose in each c_t is zeroed with probability ``dropout``.
        """
        tau, frames = self.config.tau, pose.shape[1]
        past = torch.stack([pose[:, tau - k : frames - k] for k in range(tau, 0, -1)], dim=2)
        if self.training and self.config.dropout > 0:
            keep = torch.rand(past.shape[:3] + (1,), device=pose.device) >= self.config.dropout
            past = past * keep
        controls = torch.stack([control[:, tau - k : frames - k] for k in range(tau, -1, -1)], dim=2)
        return torch.cat([past.flatten(2), controls.flatten(2)], dim=-1)

    def log_likelihood(self, pose: torch.Tensor, control: torch.Tensor) -> torch.Tensor:
        """log p(x_t | c_t, earlier frames) of each frame t = τ..T-1: (batch, T-τ), in nats."""
        z, logabsdet = self.flow(pose[:, self.config.tau :], self.conditioning(pose, control))
        log_base = -0.5 * (z**2).sum(-1) - 0.5 * self.pose_dim * math.log(2 * math.pi)
        return log_base + logabsdet

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        """Negative log-likelihood in nats per frame (summed over dimensions)."""
        nll = -self.log_likelihood(pose, control).mean()
        return nll, {"nll": nll.item()}

    @torch.inference_mode()
    def generate(
        self,
        control: torch.Tensor,
        context: torch.Tensor | None,
        temperature: float = 1.0,
        generator: torch.Generator | RowGenerators | None = None,
        precision: str = "float32",
        true_past: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Sample poses frame by frame; the noise of all frames is drawn up front.

        z (batch, T-τ, pose_dim) ~ N(0, θ²) is one draw from ``generator``, so frame t
        depends only on z_τ..z_t, the context and control up to t. With ``precision``
        "bfloat16" or "int8" (CPU only) the LSTMs and linear layers of the couplings
        multiply in that precision (``generation.models.parts.precision``); the flow's
        arithmetic stays in float32, and the result stays close to the float32 sample of
        the same seed.

        With ``true_past`` (batch, T, pose_dim; standardised, like ``context``) every c_t
        holds its poses x_{t-τ}..x_{t-1} instead of the frames generated so far (teacher
        forcing): frame t is then a prediction one frame ahead of a true past, and its
        first τ frames are the context. The couplings' LSTM state still follows the
        generated frames, as in sampling.
        """
        self.check_precision(precision)
        batch, frames, _ = control.shape
        tau = self.config.tau
        if frames < tau:
            raise ValueError(f"need at least tau={tau} frames of control, got {frames}")
        parameter = next(self.parameters())
        if precision not in available_precisions(parameter.device):
            raise ValueError(f"precision {precision} is not available on {parameter.device} "
                             f"(there: {', '.join(available_precisions(parameter.device))})")
        control = control.to(parameter)
        if true_past is not None:
            if true_past.shape != (batch, frames, self.pose_dim):
                raise ValueError(f"true_past must have shape {(batch, frames, self.pose_dim)}, not {tuple(true_past.shape)}")
            true_past = true_past.to(parameter)
            context = true_past[:, :tau]
        if context is None:
            context = control.new_zeros(batch, tau, self.pose_dim)  # the mean pose, standardised
        pose = control.new_empty(batch, frames, self.pose_dim)
        pose[:, :tau] = context.to(parameter)[:, -tau:]
        shape = (batch, frames - tau, self.pose_dim)
        noise = temperature * normal(shape, generator, dtype=pose.dtype, device=pose.device)
        # The control part of every c_t is known in advance; c_t is laid out as in conditioning().
        controls = control.unfold(1, tau + 1, 1).transpose(2, 3).flatten(2)  # (batch, T-τ, (τ+1)·control_dim)
        invert = self.flow.frame_inverse(precision)
        past = pose if true_past is None else true_past
        for t in range(tau, frames):
            conditioning = torch.cat([past[:, t - tau : t].flatten(1), controls[:, t - tau]], dim=-1)
            pose[:, t] = invert(noise[:, t - tau], conditioning)
        return pose
