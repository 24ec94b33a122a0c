"""The model kinds: which class each is, how it is controlled, and its named presets, as data.

The command line's choices, checkpoint loading, training, the study app and the
benchmarks all read this table. Importing it imports no torch: a class is imported only
when ``model_class`` asks for it, so listing kinds and presets stays cheap for the web
app. An installed package adds a kind with one more ``ModelKind``, named in its
entry-point group ``motion_study.models`` (``name = "package.module:KIND"``, a module
that imports no torch); ``load_plugins`` reads them into ``MODELS`` when this module is
imported. Plugins are code the administrator installs; nothing a user uploads is ever
imported.

A preset is a configuration by name: ``model`` replaces fields of the kind's ``Config``
(its architecture and loss), ``training`` replaces the kind's training knobs (learning
rate, Noam warm-up, gradient clipping, batch size; see ``generation.train``). A preset
name may end in one of the kind's ablations, e.g. ``cpu-MG-D``: MoGlow's ``cpu`` preset
without data dropout.
"""

from __future__ import annotations

import importlib
import warnings
from importlib import metadata
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .models.motion_model import MotionModel

# How a kind is controlled: by a path (MoGlow and its baselines) or by action and style
# labels (HVRNN and its baselines).
PATH, LABELS = "path", "labels"


@dataclass(frozen=True)
class Preset:
    """Fields of a kind's model configuration and of its training knobs that differ from the defaults."""

    model: Mapping[str, Any] = field(default_factory=dict)
    training: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ModelKind:
    """One model kind: its class as "module:Class", its control, its paper's training
    knobs, its presets and its ablations (model fields they change)."""

    target: str
    title: str  # the name in messages
    control: str  # PATH or LABELS
    training: Mapping[str, Any]
    presets: dict[str, Preset]
    ablations: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)


# Adam with gradient-norm clipping (HVRNN Sec. 4.2), for HVRNN and its baselines alike.
_LABEL_TRAINING = MappingProxyType({"learning_rate": 1e-3, "grad_clip": 0.1, "batch_size": 32})

MODELS: dict[str, ModelKind] = {
    "moglow": ModelKind(
        "generation.models.moglow:MoGlow", "MoGlow", PATH,
        # Adam with the Noam schedule; clipping guards against rare exploding steps, it is no regulariser.
        training={"learning_rate": 1e-3, "warmup_steps": 1000, "grad_clip": 100.0, "batch_size": 100},
        presets={
            # Table 1 of the paper (locomotion): about 74 M parameters for 63-D poses.
            "paper": Preset(),
            # For an hour on 2 CPU cores (README, "Trained on the real data"). τ stays at the
            # paper's 10 so its ablations mean the same. On the few Bandai-Namco takes and a
            # few thousand steps, data dropout sets the trade-off: 0 ignores the control (the
            # character glides without stepping, the paper's MG-D), 0.5 and above are still
            # far too jittery after an hour; 0.3 steps in time with the control and grows
            # smoother as it trains. A higher learning rate than the paper's reaches the same
            # training likelihood in a fraction of the steps.
            "cpu": Preset(model={"steps": 8, "tau": 10, "lstm_hidden": 128, "lstm_layers": 2, "dropout": 0.3},
                          training={"learning_rate": 3e-3, "warmup_steps": 100, "batch_size": 32}),
        },
        # The paper's ablations: no data dropout, control only, one past pose.
        ablations={"MG-D": {"dropout": 0.0}, "MG-A": {"dropout": 1.0}, "MG-H": {"tau": 1}},
    ),
    "rnn": ModelKind(
        "generation.models.rnn:RNNBaseline", "RNN", PATH,
        training={"learning_rate": 1e-3, "grad_clip": 1.0, "batch_size": 64},
        presets={
            # The paper's network: one layer of 512 units.
            "paper": Preset(),
            # Unchanged: on two CPU cores the paper's network runs 2.5 to 3 steps/s at batch 64 and
            # fits the locomotion training windows within 5 minutes (it overfits after that).
            "cpu": Preset(),
        },
    ),
    "vae": ModelKind(
        "generation.models.vae:VAEBaseline", "VAE", PATH,
        training={"learning_rate": 1e-3, "grad_clip": 1.0, "batch_size": 64},
        presets={
            # The paper's network: two BLSTM layers of 256 units per direction on each side, 2-D z.
            "paper": Preset(),
            # Half as wide: 3 to 5 steps/s on two CPU cores against 0.8 for the paper's width, so
            # 15 minutes give some 3,000 steps. Annealing lets the decoder learn to use z first.
            "cpu": Preset(model={"hidden_size": 128, "kl_anneal_steps": 500}, training={"batch_size": 32}),
        },
    ),
    "hvrnn": ModelKind(
        "generation.models.hvrnn:HVRNN", "HVRNN", LABELS, training=_LABEL_TRAINING,
        presets={
            # The sizes of Table 1.
            "paper": Preset(),
            # For one shared CPU core: about a tenth of the paper's parameters, 60-frame crops
            # (20 words) and schedules compressed to 1,000 steps.
            "cpu": Preset(model={"word_dim": 48, "word_hidden": 128, "latent_dim": 32, "feature_dim": 96,
                                 "mlp_hidden": 128, "state_dim": 192, "kl_warmup": 100, "kl_anneal": 400,
                                 "classifier_start": 300, "classifier_ramp": 300, "word_drop_steps": 800,
                                 "crop_frames": 60},
                          training={"batch_size": 16}),
        },
        # The paper's ablations: no motion-word codec, no joint hierarchy, no classifier loss.
        ablations={"SL": {"word_codec": False}, "NL": {"hierarchical": False}, "NC": {"classifier_weight": 0.0}},
    ),
    # The baselines' cpu presets: under a tenth of the parameters, and 60-frame crops as HVRNN's.
    "erd": ModelKind(
        "generation.models.erd:ERD", "erd", LABELS, training=_LABEL_TRAINING,
        presets={"paper": Preset(),
                 "cpu": Preset(model={"encoder": (128, 128), "hidden": 256, "decoder": (128, 64), "crop_frames": 60},
                               training={"batch_size": 16})},
    ),
    "quaternet": ModelKind(
        "generation.models.quaternet:QuaterNet", "quaternet", LABELS, training=_LABEL_TRAINING,
        presets={"paper": Preset(),
                 "cpu": Preset(model={"hidden": 256, "crop_frames": 60}, training={"batch_size": 16})},
    ),
}


ENTRY_POINT_GROUP = "motion_study.models"
BUILT_IN = frozenset(MODELS)


def load_plugins() -> list[str]:
    """Add the kinds installed packages name under ``ENTRY_POINT_GROUP`` to ``MODELS``; their names.

    A plugin that does not load, is no ``ModelKind`` or takes a built-in kind's name is
    left out with a warning that says why, so one broken package cannot stop the rest.
    """
    added = []
    for entry_point in metadata.entry_points(group=ENTRY_POINT_GROUP):
        where = f"model plugin {entry_point.name!r} ({entry_point.value})"
        if entry_point.name in BUILT_IN:
            warnings.warn(f"{where} is left out: {entry_point.name!r} is a built-in kind", stacklevel=2)
            continue
        try:
            kind = entry_point.load()
        except Exception as error:  # any failure of someone else's package: say which and go on
            warnings.warn(f"{where} is left out: it does not load ({type(error).__name__}: {error})", stacklevel=2)
            continue
        if not isinstance(kind, ModelKind) or kind.control not in (PATH, LABELS):
            warnings.warn(f"{where} is left out: it names no ModelKind with a path or labels control", stacklevel=2)
            continue
        MODELS[entry_point.name] = kind
        added.append(entry_point.name)
    return added


def model_kind(kind: str) -> ModelKind:
    """The registry entry of a kind (KeyError naming the known kinds)."""
    if kind not in MODELS:
        raise KeyError(f"unknown model kind {kind!r}; known kinds: {', '.join(MODELS)}")
    return MODELS[kind]


def model_class(kind: str) -> type[MotionModel]:
    """The model class of a kind, imported now (this imports torch)."""
    module, _, name = model_kind(kind).target.partition(":")
    return getattr(importlib.import_module(module), name)


def resolve_preset(kind: str, name: str) -> Preset:
    """The preset called ``name`` of a kind, with its ablation (``cpu-MG-D``) applied."""
    entry = model_kind(kind)
    base, _, ablation = name.partition("-")
    if base not in entry.presets:
        ablations = f", optionally followed by -{'/-'.join(entry.ablations)}" if entry.ablations else ""
        raise ValueError(f"unknown {entry.title} preset {name!r}; use one of {sorted(entry.presets)}{ablations}")
    preset = entry.presets[base]
    if not ablation:
        return preset
    if ablation not in entry.ablations:
        raise ValueError(f"unknown {entry.title} ablation {ablation!r}; use one of {tuple(entry.ablations)}")
    return Preset({**preset.model, **entry.ablations[ablation]}, preset.training)


def training_knobs(kind: str, name: str) -> dict[str, Any]:
    """The training knobs of a preset: the kind's paper values with the preset's changes."""
    return {**model_kind(kind).training, **resolve_preset(kind, name).training}


def preset(kind: str, name: str) -> Any:
    """The model configuration (the kind's ``Config``) of a preset; imports the model's class."""
    return model_class(kind).Config(**resolve_preset(kind, name).model)


load_plugins()
