"""The classifier outputs behind HVRNN's Table 2 and Fig. 4, for real and generated sequences.

The reference set is the held-out test sequences. Each model generates one sequence
per reference sequence, asked for its action and style and cut to its length, so
both sets have the same labels and lengths. "real" is the other half of the training
takes (``model``), which the evaluation classifiers never saw. The attribute
classifiers give, for every set, class probabilities (Inception Score) and penultimate
activations (FID). The scores themselves are computed by ``analysis`` from the file
written here (``generation`` does not import ``analysis``, nor ``analysis`` torch):

    python -m analysis hvrnn-scores OUTPUTS.npz --out DIR
"""

from __future__ import annotations

import dataclasses
import io
import os
from pathlib import Path

import numpy as np
import torch

from ..files import write_atomic
from ..generator import Generator
from .classifiers import KINDS, AttributeClassifiers, predict
from .data import AttributeData, SequenceSet

REFERENCE = "test"
REAL = "real"


@torch.no_grad()
def classifier_outputs(classifiers: AttributeClassifiers, sequences: SequenceSet, batch_size: int = 64) -> dict[str, np.ndarray]:
    """Probabilities and penultimate activations of both classifiers, and the labels."""
    features, mask, _, _ = sequences.tensors()
    result = {"action": sequences.action, "style": sequences.style}
    for kind in KINDS:
        net = classifiers[kind].eval()
        result[f"{kind}_probabilities"] = predict(net, sequences, batch_size)
        result[f"{kind}_activations"] = torch.cat([net.embed(features[i : i + batch_size], mask[i : i + batch_size])
                                                   for i in range(0, len(sequences), batch_size)]).numpy()
    return result


def require_attribute_model(generator: Generator, name: str | os.PathLike) -> None:
    if not generator.attributes:
        raise ValueError(f"{name}: a {generator.meta.kind} model follows a path; IS and FID compare "
                         "action- and style-controlled models (hvrnn, erd, quaternet)")


@torch.no_grad()
def generate_like(generator: Generator, like: SequenceSet, seed: int = 0, temperature: float = 1.0,
                  batch_size: int = 64) -> SequenceSet:
    """A generated sequence (raw angle features) for each of ``like``'s label pairs and masks."""
    require_attribute_model(generator, "the model")
    model = generator.model
    torch_generator = torch.Generator(device=generator.device).manual_seed(seed)
    frames = like.features.shape[1]
    parts = []
    for i in range(0, len(like), batch_size):
        action, style = (torch.as_tensor(a[i : i + batch_size], device=generator.device) for a in (like.action, like.style))
        standardised = model.generate(action, style, frames, temperature, torch_generator)
        parts.append(generator.pose_stats.invert(standardised.double().cpu().numpy()))
    features = (np.concatenate(parts) * like.mask[..., None]).astype(np.float32)
    return dataclasses.replace(like, features=features)


def check_compatible(generator: Generator, classifiers: AttributeClassifiers, path: str | os.PathLike) -> None:
    """Refuse a checkpoint that is not label-controlled, or whose feature size or labels
    differ from the classifiers'."""
    require_attribute_model(generator, path)
    for kind, names in (("action", generator.model.actions), ("style", generator.model.styles)):
        if tuple(names) != classifiers.vocabularies[kind].names:
            raise ValueError(f"{path}: the model's {kind}s differ from the classifiers'; "
                             "train both on the same data")
    if generator.model.pose_dim != classifiers.feature_dim:
        raise ValueError(f"{path}: the model makes {generator.model.pose_dim} features per frame, "
                         f"the classifiers read {classifiers.feature_dim}")


def evaluation_outputs(data: AttributeData, classifiers: AttributeClassifiers, checkpoints: dict[str, str | os.PathLike],
                       seed: int = 0, temperature: float = 1.0) -> dict[str, dict[str, np.ndarray]]:
    """Classifier outputs of the reference, the disjoint real half and every model, by set name."""
    for kind, vocabulary in (("action", data.actions), ("style", data.styles)):
        if classifiers.vocabularies[kind] != vocabulary:
            raise ValueError(f"the classifiers' {kind}s differ from the data's; train them on this data")
    reference = data.sequences(REFERENCE)
    outputs = {REFERENCE: classifier_outputs(classifiers, reference),
               REAL: classifier_outputs(classifiers, data.sequences("model"))}
    for name, path in checkpoints.items():
        if name in outputs:
            raise ValueError(f"a model may not be called {name!r}: that name is taken by a real set")
        generator = Generator.load(path)
        if abs(generator.fps - data.fps) > 1e-6:
            raise ValueError(f"{path}: the model runs at {generator.fps:g} fps, the data at {data.fps:g}")
        check_compatible(generator, classifiers, path)
        outputs[name] = classifier_outputs(classifiers, generate_like(generator, reference, seed, temperature))
    return outputs


def save_outputs(path: str | os.PathLike, outputs: dict[str, dict[str, np.ndarray]], data: AttributeData) -> Path:
    """Write the file ``analysis.reports.attribute_scores.read_classifier_outputs`` reads, atomically."""
    arrays = {"sets": np.array(list(outputs)), "reference": np.array(REFERENCE),
              "actions": np.array(data.actions.names), "styles": np.array(data.styles.names)}
    for name, values in outputs.items():
        arrays.update({f"{name}/{key}": value for key, value in values.items()})
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return write_atomic(Path(path), buffer.getvalue())
