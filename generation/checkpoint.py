"""The checkpoint format: safetensors weights with a JSON description in the header.

One ``.safetensors`` file holds everything needed to sample: the tensors, and under the
header's ``motion_study`` metadata key a JSON object with the model kind, its
hyperparameters, the feature specification, the standardisation statistics, the
skeleton, the training data's fingerprint, the training step, the code version and a
SHA-256 digest of the tensors. Loading never unpickles anything; a file whose JSON,
tensor names, shapes or bytes do not match is refused with a message naming what is
wrong. The optimiser state for resuming lives beside it, in ``NAME.optim.safetensors``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING

from .checkpoint_checks import check_description
from .registry import PATH, model_class, model_kind
from .store import CheckpointError, read_header, read_tensors, stored_layout, write_tensors

if TYPE_CHECKING:
    import torch

    from .models.motion_model import MotionModel

FORMAT_KEY = "motion_study"
FORMAT_VERSION = 1
# Training knobs that checkpoints kept among the model's hyperparameters before they
# moved to ``training``; reading such a header moves them there.
LEGACY_TRAINING_FIELDS = ("learning_rate", "warmup_steps", "grad_clip", "batch_size", "classifiers")


@dataclass
class CheckpointMeta:
    """The JSON half of a checkpoint."""

    kind: str
    hyperparameters: dict  # the model's configuration: its architecture and loss
    pose_dim: int
    control_dim: int
    features: dict  # {"type": "positions", "fps": 20.0, "root": {...}, ...}
    stats: dict  # {"pose": {"mean": [...], "std": [...]}, "control": {...}}
    skeleton: dict
    data_fingerprint: str
    step: int = 0
    code_version: str = ""
    metrics: dict = field(default_factory=dict)
    training: dict = field(default_factory=dict)  # the knobs of generation.train.TrainingConfig

    def to_json(self) -> str:
        return json.dumps({"format_version": FORMAT_VERSION, **dataclasses.asdict(self)})

    @classmethod
    def from_json(cls, text: str, path: Path) -> "CheckpointMeta":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as error:
            raise CheckpointError(f"{path}: the checkpoint's JSON header is invalid ({error.msg})") from None
        except RecursionError:  # thousands of nested brackets exhaust the parser's stack
            raise CheckpointError(f"{path}: the checkpoint's JSON header is nested too deeply") from None
        if not isinstance(data, dict):
            raise CheckpointError(f"{path}: the checkpoint's JSON header is not an object")
        if data.pop("format_version", None) != FORMAT_VERSION:
            raise CheckpointError(f"{path}: checkpoint format version is not {FORMAT_VERSION}")
        names = {f.name for f in dataclasses.fields(cls)}
        required = {f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
        missing, unknown = required - set(data), set(data) - names
        if missing or unknown:
            problems = [f"missing {', '.join(sorted(missing))}"] if missing else []
            problems += [f"unknown {', '.join(sorted(unknown))}"] if unknown else []
            raise CheckpointError(f"{path}: checkpoint JSON fields: {'; '.join(problems)}")
        expected_types = {"kind": str, "hyperparameters": dict, "pose_dim": int, "control_dim": int, "features": dict,
                          "stats": dict, "skeleton": dict, "data_fingerprint": str, "step": int, "metrics": dict, "training": dict}
        for name, kind in expected_types.items():
            value = data.get(name, kind())
            if not isinstance(value, kind) or isinstance(value, bool):
                raise CheckpointError(f"{path}: checkpoint JSON field {name} must be {JSON_TYPE_NAMES[kind]}, "
                                      f"not {json.dumps(value)[:40]}")
        for name in ("pose_dim", "control_dim"):
            if data[name] < 1:
                raise CheckpointError(f"{path}: checkpoint JSON field {name} must be positive, not {data[name]}")
        legacy = {name: data["hyperparameters"].pop(name) for name in LEGACY_TRAINING_FIELDS
                  if name in data["hyperparameters"]}
        return cls(**{**data, "training": {**legacy, **data.get("training", {})}})


JSON_TYPE_NAMES = {str: "a string", int: "an integer", dict: "an object"}


def code_version() -> str:
    """The package version, with the git commit when run from a checkout."""
    try:
        version = metadata.version("motion-study")
    except metadata.PackageNotFoundError:
        version = "unknown"
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent,
            capture_output=True, text=True, timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return f"{version}+{commit}" if commit else version


def save_checkpoint(path: str | os.PathLike, model: MotionModel, meta: CheckpointMeta,
                    optimizer: torch.optim.Optimizer | None = None) -> Path:
    """Write the model (and, if given, the optimiser state beside it) atomically."""
    path = write_tensors(path, model.state_dict(), {FORMAT_KEY: meta.to_json()})
    if optimizer is not None:
        state = optimizer.state_dict()
        flat = {f"{index}.{key}": value for index, entries in state["state"].items() for key, value in entries.items()}
        write_tensors(optimizer_path(path), flat, {"param_groups": json.dumps(state["param_groups"])}, digest=False)
    return path


def optimizer_path(path: Path) -> Path:
    return path.with_name(path.name.removesuffix(".safetensors") + ".optim.safetensors")


def _meta(path: Path, header: dict[str, str]) -> CheckpointMeta:
    if FORMAT_KEY not in header:
        raise CheckpointError(f"{path}: a safetensors file, but not a checkpoint of this project (no '{FORMAT_KEY}' header)")
    meta = CheckpointMeta.from_json(header[FORMAT_KEY], path)
    try:
        needs_control = model_kind(meta.kind).control == PATH
    except KeyError as error:
        raise CheckpointError(f"{path}: {error.args[0]}") from None
    check_description(path, needs_control, meta.pose_dim, meta.control_dim, meta.features, meta.stats, meta.skeleton)
    return meta


def read_meta(path: str | os.PathLike) -> CheckpointMeta:
    """The JSON description of a checkpoint, checked for form and sense (the tensors are not
    read, torch is not loaded)."""
    path = Path(path)
    return _meta(path, read_header(path))


def load_checkpoint(path: str | os.PathLike, device: str | torch.device = "cpu") -> tuple[MotionModel, CheckpointMeta]:
    """The model (in eval mode, on ``device``) and its description, fully validated.

    The description is checked from the header, and the model built under the budget of
    the file's tensors (``build_budget``), before any tensor is read.
    """
    from .build_budget import build_within

    path = Path(path)
    meta = read_meta(path)
    cls = model_class(meta.kind)
    model = build_within(path, lambda: cls(cls.Config(**meta.hyperparameters), meta.pose_dim, meta.control_dim),
                         stored_layout(path))
    tensors, _ = read_tensors(path)
    model.load_state_dict(tensors)
    return model.to(device).eval(), meta


def load_optimizer_state(path: str | os.PathLike, optimizer: torch.optim.Optimizer) -> None:
    """Restore the optimiser state saved beside a checkpoint by ``save_checkpoint``."""
    tensors, header = read_tensors(optimizer_path(Path(path)), check_digest=False)
    state: dict[int, dict[str, torch.Tensor]] = {}
    for name, tensor in tensors.items():
        index, key = name.split(".", 1)
        state.setdefault(int(index), {})[key] = tensor
    optimizer.load_state_dict({"state": state, "param_groups": json.loads(header["param_groups"])})
