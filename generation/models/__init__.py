"""The motion models, by kind; each kind has named presets of its configuration.

Preset names may carry an ablation suffix where a model defines ablations, e.g.
``cpu-MG-D`` for MoGlow without data dropout.
"""

from __future__ import annotations

from collections.abc import Callable

from .base import MotionModel
from .moglow import MoGlow, moglow_preset
from .rnn import RNNBaseline, rnn_preset
from .vae import VAEBaseline, vae_preset
from ..hvrnn.model import HVRNN, hvrnn_preset
from ..hvrnn.baselines import ERD, QuaterNet, erd_preset, quaternet_preset

MODELS: dict[str, tuple[type[MotionModel], Callable]] = {
    MoGlow.kind: (MoGlow, moglow_preset),
    RNNBaseline.kind: (RNNBaseline, rnn_preset),
    VAEBaseline.kind: (VAEBaseline, vae_preset),
    HVRNN.kind: (HVRNN, hvrnn_preset),
    ERD.kind: (ERD, erd_preset),
    QuaterNet.kind: (QuaterNet, quaternet_preset),
}


def model_class(kind: str) -> type[MotionModel]:
    """The model class of a kind (KeyError naming the known kinds)."""
    if kind not in MODELS:
        raise KeyError(f"unknown model kind {kind!r}; known kinds: {', '.join(MODELS)}")
    return MODELS[kind][0]


def preset(kind: str, name: str):
    """The configuration called ``name`` of a model kind."""
    model_class(kind)
    return MODELS[kind][1](name)
