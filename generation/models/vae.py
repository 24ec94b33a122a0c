"""MoGlow's VAE baseline (Henter et al. 2020, Sec. 4.3): a conditional VAE after Greenwood et al. (2017).

Encoder: two bidirectional LSTM layers read pose and control together; their states are
mean-pooled over time into the mean and log-variance of a small latent z, one per
sequence. Decoder: two bidirectional LSTM layers read the control with z repeated at
every frame and output the poses. Training minimises

    MSE(pose, decoded) + kl_weight · KL(q(z | pose, control) ‖ N(0, I)) / (frames · pose_dim),

which, with kl_weight = 1, is the negative evidence lower bound per pose value for a
Gaussian decoder of variance 1/2 (whose negative log-likelihood is the squared error).
Dividing the per-sequence KL by the number of pose values keeps that balance; adding the
per-sequence KL to a per-value MSE as is would weigh it thousands of times too heavily
and collapse the posterior.

At synthesis the decoder runs once with z at the prior mean (zero), as a deterministic
function of the control. Both directions of the LSTMs make it non-causal: every output
frame depends on the whole control sequence, which must be known in advance (as in the
paper), so it cannot drive a character from live input.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from .path import PathModel


@dataclass
class VAEConfig:
    hidden_size: int = 256  # LSTM units per direction
    num_layers: int = 2  # in the encoder and in the decoder
    latent_dim: int = 2
    kl_weight: float = 1.0
    # The KL weight rises linearly from 0 over this many training steps (0: no annealing),
    # so the decoder learns to use z before the prior pulls the posterior onto it.
    kl_anneal_steps: int = 0


def kl_to_standard_normal(mean: torch.Tensor, log_var: torch.Tensor) -> torch.Tensor:
    """KL(N(mean, diag(exp(log_var))) ‖ N(0, I)) in nats, summed over the last dimension."""
    return 0.5 * (mean.square() + log_var.exp() - 1.0 - log_var).sum(dim=-1)


class VAEBaseline(PathModel):
    """Conditional VAE over whole pose sequences; see the module docstring.

    ``generate`` is deterministic: z is fixed at zero, so ``temperature`` and ``generator``
    have no effect, and ``context`` is ignored. ``loss`` counts training steps (in a buffer
    saved with the weights) to anneal the KL weight.
    """

    kind = "vae"
    per_row_seeds = True  # it draws nothing
    Config = VAEConfig
    context_frames = 0

    def __init__(self, config: VAEConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        width = 2 * config.hidden_size  # both directions
        self.encoder = nn.LSTM(pose_dim + control_dim, config.hidden_size, config.num_layers,
                               batch_first=True, bidirectional=True)
        self.posterior = nn.Linear(width, 2 * config.latent_dim)
        self.decoder = nn.LSTM(control_dim + config.latent_dim, config.hidden_size, config.num_layers,
                               batch_first=True, bidirectional=True)
        self.output = nn.Linear(width, pose_dim)
        self.register_buffer("training_steps", torch.zeros((), dtype=torch.long))

    def encode(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Mean and log-variance (batch, latent_dim) of q(z | pose, control)."""
        states, _ = self.encoder(torch.cat([pose, control], dim=-1))
        mean, log_var = self.posterior(states.mean(dim=1)).chunk(2, dim=-1)
        return mean, log_var

    def decode(self, control: torch.Tensor, latent: torch.Tensor) -> torch.Tensor:
        """Poses (batch, frames, pose_dim) for control and one latent (batch, latent_dim) per sequence."""
        repeated = latent[:, None, :].expand(-1, control.shape[1], -1)
        states, _ = self.decoder(torch.cat([control, repeated], dim=-1))
        return self.output(states)

    def current_kl_weight(self) -> float:
        """The KL weight at the current training step."""
        steps = self.config.kl_anneal_steps
        ramp = min(1.0, self.training_steps.item() / steps) if steps > 0 else 1.0
        return self.config.kl_weight * ramp

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        mean, log_var = self.encode(pose, control)
        latent = mean + torch.randn_like(mean) * (0.5 * log_var).exp()
        mse = F.mse_loss(self.decode(control, latent), pose)
        kl = kl_to_standard_normal(mean, log_var).mean()
        weight = self.current_kl_weight()
        if self.training and torch.is_grad_enabled():
            self.training_steps += 1
        total = mse + weight * kl / pose[0].numel()
        return total, {"mse": mse.item(), "kl": kl.item(), "kl_weight": weight}

    @torch.no_grad()
    def generate(
        self,
        control: torch.Tensor,
        context: torch.Tensor | None = None,
        temperature: float = 1.0,
        generator: torch.Generator | None = None,
        precision: str = "float32",
    ) -> torch.Tensor:
        """Decoded poses with z at the prior mean; the same for every temperature and seed."""
        self.check_precision(precision)
        control = control.to(self.output.weight)
        latent = control.new_zeros(control.shape[0], self.config.latent_dim)
        return self.decode(control, latent)
