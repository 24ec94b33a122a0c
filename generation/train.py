"""Training any model on a motion dataset, with validation, checkpoints and resuming.

One loop serves every model: Adam, an optional Noam warm-up (MoGlow), gradient-norm
clipping, random minibatches of training windows (these knobs are a ``TrainingConfig``,
recorded in the checkpoint beside the model's configuration), and at each evaluation the validation
loss (MoGlow's NLL on the validation takes) and a checkpoint written atomically. The
validation takes are held out of training for choosing checkpoints; the test takes are
left alone for ``generation evaluate`` and the papers' tables.

Path-controlled models learn from a ``MotionDataset``'s windows of poses and control;
attribute-controlled models (``AttributeModel``: HVRNN, ERD, QuaterNet) from an
``AttributeData``'s padded angle sequences with masks and labels. Either way a batch is
a dict of tensors passed to ``model.loss`` by name. HVRNN's classifier loss reads frozen
attribute classifiers, which the trainer loads from their file and hands to the model.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from .checkpoint import CheckpointMeta, code_version, load_checkpoint, load_optimizer_state, read_meta, save_checkpoint
from .hvrnn.classifiers import AttributeClassifiers
from .models.attribute import AttributeModel
from .models.motion_model import MotionModel
from .models.hvrnn import HVRNN
from .motion.dataset import MotionDataset
from .registry import model_class, resolve_preset, training_knobs
from .store import CheckpointError

KEYS = ("pose", "control")
# The training part of an attribute dataset: every training take (the classifiers of
# the classifier loss see only half of them, as in the paper).
ATTRIBUTE_TRAINING_PART = "train"


@dataclass(frozen=True)
class TrainingConfig:
    """The knobs of the loop that shape what is learnt; ``generation.registry`` holds each
    kind's values and its presets' changes."""

    learning_rate: float  # of Adam
    grad_clip: float  # gradient-norm clipping
    batch_size: int
    warmup_steps: int = 0  # of the Noam schedule; 0 keeps the learning rate constant
    classifiers: str = ""  # HVRNN's classifier loss: the attribute classifiers' file

    def __post_init__(self) -> None:
        for name in ("learning_rate", "grad_clip", "batch_size"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, not {getattr(self, name)}")
        if self.warmup_steps < 0:
            raise ValueError(f"warmup_steps must be 0 or more, not {self.warmup_steps}")


@dataclass(frozen=True)
class TrainOptions:
    """How a run goes, without changing what a step learns."""

    steps: int = 2000
    eval_every: int = 250
    seed: int = 0
    device: str = "cpu"


def noam_factor(step: int, warmup: int) -> float:
    """The learning-rate factor of the Noam schedule, 1 at the end of the warm-up."""
    if warmup <= 0:
        return 1.0
    step = max(step, 1)
    return min(step / warmup, math.sqrt(warmup / step))


def tensors(dataset: MotionDataset, split: str, device: str) -> dict[str, torch.Tensor]:
    windows = dataset.windows(split, KEYS)
    if len(windows["pose"]) == 0:
        raise ValueError(f"the dataset has no {split} windows of {dataset.options.window_frames} frames")
    return {k: torch.as_tensor(v, dtype=torch.float32, device=device) for k, v in windows.items()}


def attribute_tensors(data, part: str, standardization: str, device: str) -> dict[str, torch.Tensor]:
    """Padded sequences of an ``AttributeData`` part as a batch dict: pose, mask, action, style."""
    pose, mask, action, style = data.sequences(part, data.standardizer(standardization)).tensors(device)
    return {"pose": pose, "mask": mask, "action": action, "style": style}


@dataclass
class TrainingData:
    """A dataset as the loop sees it: batches by name, and what a checkpoint records of it."""

    train: dict[str, torch.Tensor]
    validation: dict[str, torch.Tensor]
    pose_dim: int
    control_dim: int
    features: dict
    stats: dict
    skeleton: dict
    fingerprint: str
    labels: dict  # configuration fields taken from the data (attribute models' vocabularies)


def training_data(cls: type[MotionModel], dataset, device: str) -> TrainingData:
    """Windows of a ``MotionDataset`` for path models, sequences of an ``AttributeData`` for attribute models."""
    if issubclass(cls, AttributeModel):
        if not hasattr(dataset, "sequences"):
            raise ValueError(f"a {cls.kind} model learns from labelled angle sequences (generation.hvrnn.data.AttributeData)")
        train_part = attribute_tensors(dataset, ATTRIBUTE_TRAINING_PART, cls.standardization, device)
        motion = dataset.dataset
        return TrainingData(
            train_part, attribute_tensors(dataset, "validation", cls.standardization, device),
            dataset.feature_dim, len(dataset.actions) + len(dataset.styles),
            {"type": "angles", "dataset_options": motion.options.to_dict(), "angle_spec": motion.angle_spec.to_dict(),
             "part": ATTRIBUTE_TRAINING_PART},
            {"pose": dataset.standardizer(cls.standardization).to_dict()},
            motion.skeleton.to_dict(), motion.fingerprint,
            {"actions": dataset.actions.names, "styles": dataset.styles.names},
        )
    if not isinstance(dataset, MotionDataset):
        raise ValueError(f"a {cls.kind} model learns from a MotionDataset's windows")
    train_part = tensors(dataset, "train", device)
    return TrainingData(
        train_part, tensors(dataset, "validation", device), train_part["pose"].shape[-1], train_part["control"].shape[-1],
        {"type": "positions", "dataset_options": dataset.options.to_dict()},
        {k: dataset.stats[k].to_dict() for k in KEYS}, dataset.skeleton.to_dict(), dataset.fingerprint, {},
    )


def batch_count(data: dict[str, torch.Tensor]) -> int:
    return len(data["pose"])


@torch.no_grad()
def evaluate_loss(model: MotionModel, data: dict[str, torch.Tensor], batch_size: int = 64) -> float:
    """The mean loss over all windows (model in eval mode: no dropout)."""
    was_training = model.training
    model.eval()
    total, count = 0.0, 0
    for start in range(0, batch_count(data), batch_size):
        batch = {k: v[start : start + batch_size] for k, v in data.items()}
        loss, _ = model.loss(**batch)
        total += float(loss) * batch_count(batch)
        count += batch_count(batch)
    model.train(was_training)
    return total / count


def checkpoint_meta(model: MotionModel, training: TrainingConfig, data: TrainingData, step: int,
                    metrics: dict) -> CheckpointMeta:
    return CheckpointMeta(
        kind=model.kind,
        hyperparameters=dataclasses.asdict(model.config),
        training=dataclasses.asdict(training),
        pose_dim=model.pose_dim,
        control_dim=model.control_dim,
        features=data.features,
        stats=data.stats,
        skeleton=data.skeleton,
        data_fingerprint=data.fingerprint,
        step=step,
        code_version=code_version(),
        metrics=metrics,
    )


def load_loss_classifiers(model: HVRNN, path: str) -> None:
    """Hand HVRNN the frozen attribute classifiers of its classifier loss, from ``path``,
    checked against the model's labels and features before training starts."""
    if not path:
        raise ValueError("the classifier loss (classifier_weight > 0) needs the attribute classifiers' file "
                         "(--classifiers on the command line); the NC ablation needs none")
    classifiers = AttributeClassifiers.load(path)
    if list(classifiers.vocabularies["action"].names) != list(model.actions) or \
            list(classifiers.vocabularies["style"].names) != list(model.styles):
        raise ValueError(f"{path}: the classifiers' labels differ from the training data's")
    if classifiers.feature_dim != model.pose_dim:
        raise ValueError(f"{path}: the classifiers read {classifiers.feature_dim} features per frame, "
                         f"the model makes {model.pose_dim}")
    model.use_classifiers((classifiers["action"], classifiers["style"]))


def _training_config(path: Path, knobs: dict) -> TrainingConfig:
    try:
        return TrainingConfig(**knobs)
    except (TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: the training knobs do not build a training configuration ({error})") from None


def split_overrides(kind: str, overrides: dict) -> tuple[dict, dict]:
    """``overrides`` as (model configuration fields, training knobs); an unknown name is refused."""
    model_fields = {f.name: f for f in dataclasses.fields(model_class(kind).Config)}
    knobs = {f.name: f for f in dataclasses.fields(TrainingConfig)}
    unknown = sorted(set(overrides) - set(model_fields) - set(knobs))
    if unknown:
        raise ValueError(f"{kind} has no setting {', '.join(unknown)} (model: {', '.join(sorted(model_fields))}; "
                         f"training: {', '.join(sorted(knobs))})")
    fields = {**model_fields, **knobs}
    checked = {name: _of_field_type(fields[name], value) for name, value in overrides.items()}
    return ({k: v for k, v in checked.items() if k in model_fields},
            {k: v for k, v in checked.items() if k in knobs})


_SCALAR_TYPES = {"float": float, "int": int, "bool": bool, "str": str}


def _of_field_type(field: dataclasses.Field, value):
    """``value`` as ``field``'s declared type (an int where a float is declared is taken; a
    JSON list becomes a tuple); a value of another type is refused with the field's name."""
    wanted = _SCALAR_TYPES.get(field.type if isinstance(field.type, str) else getattr(field.type, "__name__", ""))
    if wanted is None:
        return tuple(value) if isinstance(value, list) else value
    if wanted is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if type(value) is not wanted:
        raise ValueError(f"setting {field.name} must be {wanted.__name__}, not {value!r}")
    return value


def _with_changed_config(path: Path, model: MotionModel, changes: dict) -> MotionModel:
    """The model rebuilt with ``changes`` to its configuration and its trained weights;
    refused where the weights no longer fit (a change to the architecture)."""
    config = dataclasses.replace(model.config, **changes)
    changed = type(model)(config, model.pose_dim, model.control_dim)
    try:
        changed.load_state_dict(model.state_dict())
    except RuntimeError:
        raise CheckpointError(f"{path}: cannot change {', '.join(changes)} when resuming: "
                              "the trained weights no longer fit the model") from None
    return changed.to(next(model.parameters()).device)


def best_path(out: Path) -> Path:
    """Where the checkpoint with the lowest validation loss so far is kept."""
    return out.with_name(out.name.removesuffix(".safetensors") + ".best.safetensors")


def train(
    kind: str,
    preset_name: str,
    dataset,
    out: str | os.PathLike,
    options: TrainOptions = TrainOptions(),
    resume: bool = False,
    progress: bool = True,
    overrides: dict | None = None,
) -> CheckpointMeta:
    """Train (or with ``resume`` continue) a model; returns the last checkpoint's description.

    ``dataset`` is a ``MotionDataset`` (path models) or an ``AttributeData`` (attribute
    models). ``overrides`` replaces fields of the preset's model configuration or training
    knobs (``TrainingConfig``); resuming takes both from the checkpoint, and applies
    ``overrides`` from the checkpoint's step on (recorded under ``metrics["changes"]``).
    ``out`` always holds the latest state (and its optimiser, for resuming);
    ``NAME.best.safetensors`` beside it the state with the lowest validation loss.
    """
    out = Path(out)
    torch.manual_seed(options.seed)
    cls = model_class(kind)
    data = training_data(cls, dataset, options.device)
    train_data, val_data = data.train, data.validation

    model_changes, knob_changes = split_overrides(kind, overrides or {})
    history: list[dict] = []
    if resume and out.exists():
        model, meta = load_checkpoint(out, options.device)
        if meta.data_fingerprint != data.fingerprint:
            raise CheckpointError(f"{out}: trained on other data (fingerprint {meta.data_fingerprint[:12]}, "
                                  f"this dataset {data.fingerprint[:12]}); cannot resume")
        start, history = meta.step, meta.metrics.get("history", [])
        changes = meta.metrics.get("changes", [])
        # A setting the checkpoint already has is no change (a resumed script repeats its --set).
        model_changes = {k: v for k, v in model_changes.items() if meta.hyperparameters.get(k) != v}
        knob_changes = {k: v for k, v in knob_changes.items() if meta.training.get(k) != v}
        if model_changes:
            model = _with_changed_config(out, model, model_changes)
        model.train()
        training = _training_config(out, {**meta.training, **knob_changes})
        if model_changes or knob_changes:  # the checkpoint says what changed from which step on
            changes = changes + [{"step": start, **model_changes, **knob_changes}]
    else:
        config = cls.Config(**{**resolve_preset(kind, preset_name).model, **data.labels, **model_changes})
        model = cls(config, data.pose_dim, data.control_dim).to(options.device)
        training = TrainingConfig(**{**training_knobs(kind, preset_name), **knob_changes})
        start, changes = 0, []
    model.prepare(dataset)
    if isinstance(model, HVRNN) and model.config.classifier_weight > 0:
        load_loss_classifiers(model, training.classifiers)
    optimizer = torch.optim.Adam(model.parameters(), lr=training.learning_rate)
    if start:
        load_optimizer_state(out, optimizer)
    batches = torch.Generator(device="cpu").manual_seed(options.seed + start)

    elapsed = history[-1]["seconds"] if history else 0.0
    clock = time.perf_counter()
    bar = tqdm(range(start, options.steps), desc=f"training {kind}", unit="step", disable=not progress,
               initial=start, total=options.steps)
    recent: list[float] = []
    for step in bar:
        for group in optimizer.param_groups:
            group["lr"] = training.learning_rate * noam_factor(step + 1, training.warmup_steps)
        index = torch.randint(batch_count(train_data), (training.batch_size,), generator=batches).to(options.device)
        loss, metrics = model.loss(**{k: v[index] for k, v in train_data.items()})
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), training.grad_clip)
        optimizer.step()
        recent.append(loss.detach().item())
        if not np.isfinite(recent[-1]):
            raise FloatingPointError(f"the training loss became {recent[-1]} at step {step + 1}; "
                                     "try a lower learning rate or stronger gradient clipping")
        done = step + 1
        if done % options.eval_every == 0 or done == options.steps:
            val = evaluate_loss(model, val_data)
            seconds = elapsed + time.perf_counter() - clock
            history.append({"step": done, "train_loss": float(np.mean(recent)), "val_loss": val, "seconds": round(seconds, 1)})
            recent = []
            bar.set_postfix(train=f"{history[-1]['train_loss']:.3f}", val=f"{val:.3f}")
            metrics = {"val_loss": val, "history": history, **({"changes": changes} if changes else {})}
            meta = checkpoint_meta(model, training, data, done, metrics)
            save_checkpoint(out, model, meta, optimizer)
            # Small baselines overfit the few training takes early: keep the best as well.
            if val <= min(h["val_loss"] for h in history):
                save_checkpoint(best_path(out), model, meta)
    bar.close()
    return read_meta(out)
