"""The denoising autoencoder (Sec. 3.1 and Table 1 of Ghorbani et al.) that cleans the
training data before HVRNN learns from it.

Two 1-D convolutions with ReLU encode a sequence; two transposed convolutions decode
it (with a ReLU between them: without one they would compose into a single linear
layer); the layer sizes are this project's choice. The network starts as the identity
map (see ``Denoiser._start_at_identity``). It is trained to undo a corruption of 10 %
of the input values (frame × dimension entries), to which N(0, 0.5²) noise is added,
in the standardised space of ``inputs.InputNormalizer`` so that every dimension is
corrupted on the same scale; the loss is the mean squared error on real frames.
Applying it returns raw features with unit quaternions again.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..checkpoints.store import CheckpointError, tensor_digest
from .data import ROOT_DIMS, AttributeData, SequenceSet
from .fitting import fit
from .inputs import InputNormalizer
from .networks import load_network, load_state, save_network

NETWORK_KIND = "denoiser"


@dataclass(frozen=True)
class DenoiserConfig:
    channels: tuple[int, int] = (256, 256)  # at least twice the feature size: see _start_at_identity
    kernel: int = 3
    stride: int = 1
    corrupt_fraction: float = 0.1
    noise_std: float = 0.5
    steps: int = 2000
    batch_size: int = 32
    # Adam moves every weight by about lr at first; a larger rate throws the
    # identity start far off before the gradients say where to go.
    lr: float = 1e-4
    crop_frames: int = 64  # training windows: the convolutions see only a few frames anyway


class Denoiser(nn.Module):
    """``forward(normalized, mask)``: the clean estimate of standardised features."""

    def __init__(self, config: DenoiserConfig, feature_dim: int) -> None:
        super().__init__()
        (a, b), k, s = config.channels, config.kernel, config.stride
        if s < 1 or k < s or (k - s) % 2:
            raise ValueError(f"the denoiser needs kernel - stride even and non-negative, got kernel {k}, stride {s}")
        self.config, self.feature_dim = config, feature_dim
        self.inputs = InputNormalizer(feature_dim)
        # Padding (k - s) / 2 makes each layer divide (or multiply) the length by s exactly.
        p = (k - s) // 2
        self.encoder = nn.Sequential(nn.Conv1d(feature_dim, a, k, s, p), nn.ReLU(), nn.Conv1d(a, b, k, s, p), nn.ReLU())
        self.decoder = nn.Sequential(nn.ConvTranspose1d(b, a, k, s, p), nn.ReLU(), nn.ConvTranspose1d(a, feature_dim, k, s, p))
        if s == 1 and min(a, b) >= 2 * feature_dim:
            self._start_at_identity()

    @torch.no_grad()
    def _start_at_identity(self) -> None:
        """Start as the identity map: the first layer splits x into ReLU(x) and ReLU(−x),
        the middle layers pass them on, the last subtracts them; every other weight starts
        at a hundredth of its default size. Training then learns corrections to "no change",
        which the corrupted input's own error bounds, instead of first having to learn to
        copy 86 dimensions through a random network (slow, and on a few hundred sequences
        it never gets near: held-out errors stayed ten times the input's)."""
        d, centre = self.feature_dim, self.config.kernel // 2
        layers = [self.encoder[0], self.encoder[2], self.decoder[0], self.decoder[2]]
        for layer in layers:
            layer.weight.mul_(0.01)
            layer.bias.zero_()
        eye = torch.eye(d)
        # Conv1d weights are (out, in, k); ConvTranspose1d weights are (in, out, k).
        self.encoder[0].weight[:d, :, centre] = eye
        self.encoder[0].weight[d : 2 * d, :, centre] = -eye
        for layer in (self.encoder[2], self.decoder[0]):
            layer.weight[: 2 * d, : 2 * d, centre] = torch.eye(2 * d)
        self.decoder[2].weight[:d, :, centre] = eye
        self.decoder[2].weight[d : 2 * d, :, centre] = -eye

    def forward(self, normalized: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        frames = normalized.shape[1]
        pad = -frames % self.config.stride ** 2
        x = (normalized * mask.unsqueeze(-1).to(normalized.dtype)).transpose(1, 2)
        x = nn.functional.pad(x, (0, pad))
        return self.decoder(self.encoder(x))[..., :frames].transpose(1, 2)

    def corrupt(self, normalized: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
        """``normalized`` with a random ``corrupt_fraction`` of its values perturbed by N(0, noise_std²)."""
        chosen = torch.rand(normalized.shape, generator=generator, device=normalized.device) < self.config.corrupt_fraction
        noise = torch.randn(normalized.shape, generator=generator, device=normalized.device) * self.config.noise_std
        return normalized + chosen * noise

    @torch.no_grad()
    def clean(self, features: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Denoised raw features (batch, frames, dims): unit quaternions, zero padding."""
        self.eval()
        clean = self.inputs.invert(self(self.inputs(features), mask))
        quats = clean[..., ROOT_DIMS:].unflatten(-1, (-1, 4))
        quats = quats / quats.norm(dim=-1, keepdim=True).clamp_min(1e-8)
        return torch.cat([clean[..., :ROOT_DIMS], quats.flatten(-2)], -1) * mask.unsqueeze(-1)

    def apply(self, sequences: SequenceSet, batch_size: int = 64) -> SequenceSet:
        """The sequences denoised, with the same labels and masks."""
        features, mask, _, _ = sequences.tensors()
        parts = [self.clean(features[i : i + batch_size], mask[i : i + batch_size]) for i in range(0, len(sequences), batch_size)]
        return dataclasses.replace(sequences, features=torch.cat(parts).numpy())

    def save(self, path: str | os.PathLike, data_fingerprint: str, metrics: dict) -> Path:
        return save_network(path, self, NETWORK_KIND, {
            "config": dataclasses.asdict(self.config), "feature_dim": self.feature_dim,
            "data_fingerprint": data_fingerprint, "metrics": metrics,
        })

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Denoiser":
        tensors, description = load_network(path, NETWORK_KIND)
        try:
            config = DenoiserConfig(**{**description["config"], "channels": tuple(description["config"]["channels"])})
            model = cls(config, int(description["feature_dim"]))
        except (KeyError, TypeError, ValueError) as error:
            raise CheckpointError(f"{path}: cannot build the denoiser its description names ({error})") from None
        load_state(path, model, tensors)
        return model.eval()


def masked_mse(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The mean squared difference over the real frames (and every dimension)."""
    return ((a - b) ** 2)[mask].mean()


def train_denoiser(data: AttributeData, config: DenoiserConfig = DenoiserConfig(), part: str = "train",
                   seed: int = 0, progress: bool = False) -> tuple[Denoiser, list[float]]:
    """A denoiser trained on ``part`` (all training takes by default); and its step losses."""
    sequences = data.sequences(part)
    torch.manual_seed(seed)  # the initial weights
    denoiser = Denoiser(config, data.feature_dim)
    denoiser.inputs.fit(data.sequences("train"), data.quaternion_reference())
    features, mask, _, _ = sequences.tensors()
    with torch.no_grad():
        clean = denoiser.inputs(features)
    noise = torch.Generator().manual_seed(seed)

    lengths = mask.sum(1)
    window = torch.arange(min(config.crop_frames, clean.shape[1]))

    def batch_loss(index: np.ndarray) -> torch.Tensor:
        index = torch.as_tensor(index)
        room = (lengths[index] - len(window)).clamp_min(0)
        start = (torch.rand(len(index), generator=noise) * (room + 1)).long().clamp(max=room)
        frames = start[:, None] + window
        x, m = clean[index[:, None], frames], mask[index[:, None], frames]
        return masked_mse(denoiser(denoiser.corrupt(x, noise), m), x, m)

    losses = fit(denoiser, batch_loss, len(sequences), config.steps, config.batch_size, config.lr,
                 seed=seed, progress=progress, description="denoiser")
    return denoiser, losses


@torch.no_grad()
def denoising_errors(denoiser: Denoiser, sequences: SequenceSet, seed: int = 0) -> dict[str, float]:
    """Mean squared errors (standardised units, real frames) against the clean data of
    the corrupted input and of the denoiser's output from it."""
    denoiser.eval()
    features, mask, _, _ = sequences.tensors()
    clean = denoiser.inputs(features)
    corrupted = denoiser.corrupt(clean, torch.Generator().manual_seed(seed))
    return {"corrupted": float(masked_mse(corrupted, clean, mask)),
            "denoised": float(masked_mse(denoiser(corrupted, mask), clean, mask))}


def denoise_training_data(data: AttributeData, denoiser: Denoiser) -> AttributeData:
    """``data`` with every training clip's angle features denoised (each clip whole;
    held-out clips untouched), so any model trained on it learns from cleaned data.
    The fingerprint records the denoiser, so checkpoints tell the two data apart."""
    angles = data.dataset.arrays["angles"].copy()
    for clip in data.clips("train"):
        features = torch.as_tensor(angles[clip.start : clip.stop])[None]
        angles[clip.start : clip.stop] = denoiser.clean(features, torch.ones(features.shape[:2], dtype=torch.bool))[0].numpy()
    weights = tensor_digest(denoiser.state_dict())[:16]
    dataset = dataclasses.replace(data.dataset, arrays={**data.dataset.arrays, "angles": angles},
                                  fingerprint=f"{data.dataset.fingerprint}+denoised-{weights}")
    return dataclasses.replace(data, dataset=dataset)
