"""Attribute classifiers (Sec. 3.4 of Ghorbani et al.): an angle sequence's action or style.

Each is three 1-D convolutions over time with ReLU, an average over the real frames
(adaptive average pooling to one step, restricted by the mask) and a linear layer.
HVRNN uses their intermediate activations and labels in its loss; the evaluation uses
their class probabilities (Inception Score) and pooled activations (FID).

They take raw angle features, as ``data.AttributeData.sequences`` gives them without a
standardiser, and prepare them themselves (``inputs.InputNormalizer``: quaternion signs
aligned, then standardised), so real data and every model's output are judged alike.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..checkpoints.store import CheckpointError
from .data import AttributeData, SequenceSet, Vocabulary
from .fitting import fit
from .inputs import InputNormalizer
from .networks import load_network, load_state, save_network

KINDS = ("action", "style")
NETWORK_KIND = "attribute-classifiers"


@dataclass(frozen=True)
class ClassifierConfig:
    channels: tuple[int, ...] = (64, 128, 128)
    kernel: int = 5
    dropout: float = 0.3
    # Training: random crops of at least min_crop frames make a classifier judge the
    # style of any stretch of motion, not of whole clips only (and multiply the data).
    steps: int = 1500
    batch_size: int = 32
    lr: float = 1e-3
    min_crop: int = 45


def masked_average(h: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The mean of ``h`` (batch, channels, frames) over the frames where ``mask`` (batch, frames) is true."""
    weights = mask.to(h.dtype).unsqueeze(1)
    return (h * weights).sum(-1) / weights.sum(-1).clamp_min(1.0)


class AttributeClassifier(nn.Module):
    """One classifier: ``forward(features, mask) -> (logits, activations)``."""

    def __init__(self, config: ClassifierConfig, feature_dim: int, n_classes: int) -> None:
        super().__init__()
        self.config = config
        self.inputs = InputNormalizer(feature_dim)
        widths = (feature_dim, *config.channels)
        self.convs = nn.ModuleList(
            nn.Conv1d(a, b, config.kernel, padding=config.kernel // 2) for a, b in zip(widths[:-1], widths[1:]))
        self.dropout = nn.Dropout(config.dropout)
        self.linear = nn.Linear(widths[-1], n_classes)

    def activations(self, features: torch.Tensor, mask: torch.Tensor) -> list[torch.Tensor]:
        """The output (batch, channels, frames) of each convolution, zero on padding."""
        weights = mask.to(features.dtype).unsqueeze(1)
        # Zeroing the padding before every layer makes a sequence's output independent
        # of how much padding follows it.
        h = self.inputs(features).transpose(1, 2) * weights
        result = []
        for conv in self.convs:
            h = torch.relu(conv(h)) * weights
            result.append(h)
        return result

    def forward(self, features: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        activations = self.activations(features, mask)
        return self.linear(self.dropout(masked_average(activations[-1], mask))), activations

    def embed(self, features: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """The penultimate activations (batch, channels): what FID compares."""
        return masked_average(self.activations(features, mask)[-1], mask)


class AttributeClassifiers(nn.Module):
    """The action and the style classifier of one dataset, saved and loaded together."""

    def __init__(self, config: ClassifierConfig, feature_dim: int, actions: Vocabulary, styles: Vocabulary) -> None:
        super().__init__()
        self.config, self.feature_dim = config, feature_dim
        self.vocabularies = {"action": actions, "style": styles}
        self.nets = nn.ModuleDict({kind: AttributeClassifier(config, feature_dim, len(v)) for kind, v in self.vocabularies.items()})

    def __getitem__(self, kind: str) -> AttributeClassifier:
        if kind not in KINDS:
            raise KeyError(f"unknown classifier {kind!r}; use one of {KINDS}")
        return self.nets[kind]

    def fit_inputs(self, sequences: SequenceSet, reference: np.ndarray) -> None:
        for net in self.nets.values():
            net.inputs.fit(sequences, reference)

    def save(self, path: str | os.PathLike, data_fingerprint: str, metrics: dict) -> Path:
        return save_network(path, self, NETWORK_KIND, {
            "config": dataclasses.asdict(self.config), "feature_dim": self.feature_dim,
            "actions": list(self.vocabularies["action"].names), "styles": list(self.vocabularies["style"].names),
            "data_fingerprint": data_fingerprint, "metrics": metrics,
        })

    @classmethod
    def load(cls, path: str | os.PathLike) -> "AttributeClassifiers":
        tensors, description = load_network(path, NETWORK_KIND)
        try:
            config = ClassifierConfig(**{**description["config"], "channels": tuple(description["config"]["channels"])})
            model = cls(config, int(description["feature_dim"]), Vocabulary("action", tuple(description["actions"])),
                        Vocabulary("style", tuple(description["styles"])))
        except (KeyError, TypeError, ValueError) as error:
            raise CheckpointError(f"{path}: cannot build the classifiers its description names ({error})") from None
        load_state(path, model, tensors)
        return model.eval()


def random_crops(mask: torch.Tensor, min_frames: int, generator: torch.Generator) -> torch.Tensor:
    """A mask keeping one random stretch of at least ``min_frames`` (or all, if shorter)
    real frames of each row. The classifiers are translation-equivariant and pool over
    the mask, so narrowing the mask is the same as cutting the sequence."""
    lengths = mask.sum(1)
    shortest = lengths.clamp(max=min_frames)
    u = torch.rand(len(mask), 2, generator=generator, device=mask.device)
    crop = shortest + (u[:, 0] * (lengths - shortest + 1)).long().clamp(max=lengths - shortest)
    start = (u[:, 1] * (lengths - crop + 1)).long().clamp(max=lengths - crop)
    t = torch.arange(mask.shape[1], device=mask.device)
    return mask & (t >= start[:, None]) & (t < (start + crop)[:, None])


def train_classifiers(data: AttributeData, config: ClassifierConfig = ClassifierConfig(), part: str = "classifier",
                      seed: int = 0, progress: bool = False) -> tuple[AttributeClassifiers, dict[str, list[float]]]:
    """Both classifiers, trained with cross entropy on ``part``; and each one's step losses."""
    sequences = data.sequences(part)
    torch.manual_seed(seed)  # the initial weights
    classifiers = AttributeClassifiers(config, data.feature_dim, data.actions, data.styles)
    classifiers.fit_inputs(data.sequences("train"), data.quaternion_reference())
    features, mask, action, style = sequences.tensors()
    labels = {"action": action, "style": style}
    crops = torch.Generator().manual_seed(seed)
    history = {}
    for kind in KINDS:
        net = classifiers[kind]

        def batch_loss(index: np.ndarray, net=net, target=labels[kind]) -> torch.Tensor:
            index = torch.as_tensor(index)
            logits, _ = net(features[index], random_crops(mask[index], config.min_crop, crops))
            return nn.functional.cross_entropy(logits, target[index])

        history[kind] = fit(net, batch_loss, len(sequences), config.steps, config.batch_size, config.lr,
                            seed=seed, progress=progress, description=f"{kind} classifier")
    return classifiers.eval(), history


@torch.no_grad()
def predict(net: AttributeClassifier, sequences: SequenceSet, batch_size: int = 64) -> np.ndarray:
    """Class probabilities (n, classes) of every sequence."""
    net.eval()
    features, mask, _, _ = sequences.tensors()
    parts = [torch.softmax(net(features[i : i + batch_size], mask[i : i + batch_size])[0], -1)
             for i in range(0, len(sequences), batch_size)]
    return torch.cat(parts).numpy()


def accuracy(classifiers: AttributeClassifiers, sequences: SequenceSet) -> dict[str, float]:
    """The fraction of sequences whose action (style) each classifier names correctly."""
    truth = {"action": sequences.action, "style": sequences.style}
    return {kind: float((predict(classifiers[kind], sequences).argmax(1) == truth[kind]).mean()) for kind in KINDS}
