"""Checkpoints of the authors' public MoGlow code (StyleGestures) as project checkpoints.

    python -m generation import-stylegestures trained.pkg --hparams locomotion.json \\
        --data data/locomotion --out moglow-authors.safetensors

The authors' trainer saves ``{"global_step", "graph", "optim", "criterion"}`` with
``torch.save``; it is read with ``weights_only=True`` only, so a file that needs
anything but tensors, numbers and strings is refused. Their code keeps no
standardisation statistics: it refits them on every run from the training clips
(``all_locomotion_train_{fps}fps.npz`` in its data folder), so the import does the same.

Where their model differs from ``generation.models.moglow`` the difference is either an
option of the ``moglow`` configuration (the coupling's scale, ``sigmoid(h + 2) + 1e-6``)
or an exact rearrangement of the tensors done here:

* the coupling network's last layer interleaves (shift, scale) outputs; ours emits all
  scales, then all shifts: its rows are reordered;
* actnorm parameters are (1, C, 1) and not marked initialised: reshaped and marked;
* the LU factors are stored unmasked: masked (they are masked when used anyway);
* their LSTMs have two layers whatever ``Glow.num_layers`` says: the layer count is read
  from the tensors.

Their locomotion control is (sideways, forward, minus yaw) displacement per frame,
frame i holding the step from i to i+1 in the root frame at i+1; ours is velocity per
second from the previous frame. The checkpoint's ``control_layout`` feature records
theirs, and ``stylegestures_control`` converts a path into it before standardising.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pickle
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .checkpoint import CheckpointMeta, code_version, save_checkpoint
from .models.moglow import MoGlow, MoGlowConfig
from .motion.dataset import Standardizer
from .motion.dataset_options import DatasetOptions
from .motion.root import integrate, to_root_frame
from .motion.types import Skeleton

# The public code this importer was checked against (github.com/simonalexanderson/StyleGestures).
SUPPORTED_COMMIT = "bd906cf7d140972262920ed8774407e9dbd2a875"

CONTROL_LAYOUT = "stylegestures"

# Their locomotion data's 21 joints: hips, left leg, right leg, spine to head, left arm,
# right arm (parents from their animation code). The names are ours: their data has none.
JOINTS = ("Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToe", "RightUpLeg", "RightLeg", "RightFoot", "RightToe",
          "Spine", "Spine1", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
          "RightShoulder", "RightArm", "RightForeArm", "RightHand")
PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 11, 13, 14, 15, 11, 17, 18, 19)
POSE_DIM = 3 * len(JOINTS)
CONTROL_DIM = 3
# Their mirroring swaps these joint ranges and negates x of the swapped joints only (the
# spine's x is left as it is) and negates the sideways and yaw control.
MIRRORED_LIMBS = ((1, 5), (13, 17))  # first joints of the (left, right) 4-joint chains
VALIDATION_CLIPS = 100  # the last clips of their training file, held out by their loader

# What the importer accepts of their hyperparameters (others change the model).
REQUIRED = {("Glow", "flow_permutation"): "invconv", ("Glow", "LU_decomposed"): True,
            ("Glow", "flow_coupling"): "affine", ("Glow", "network_model"): "LSTM",
            ("Glow", "distribution"): "normal", ("Data", "n_lookahead"): 0}
# Their coupling's scale, sigmoid(h + 2) + 1e-6.
SCALE_OFFSET, SCALE_FLOOR = 2.0, 1e-6


class StyleGesturesError(ValueError):
    """An input the importer cannot use; the message names the file and what is wrong."""


@dataclass(frozen=True)
class ReferenceHparams:
    """The values of their hparams JSON that decide the model and its data."""

    steps: int  # Glow.K
    hidden: int  # Glow.hidden_channels
    tau: int  # Data.seqlen
    fps: float  # Data.framerate
    framerate_text: str  # as their loader writes it into the data file's name
    dropout: float
    mirror: bool
    reverse_time: bool


def read_hparams(path: str | os.PathLike) -> ReferenceHparams:
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as error:
        raise StyleGesturesError(f"{path}: cannot read the hparams ({error.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise StyleGesturesError(f"{path}: not a JSON file ({error})") from None

    def value(section: str, key: str, kind: type | tuple[type, ...]):
        part = data.get(section) if isinstance(data, dict) else None
        found = part.get(key) if isinstance(part, dict) else None
        if found is None or not isinstance(found, kind) or (kind is not bool and isinstance(found, bool)):
            raise StyleGesturesError(f"{path}: {section}.{key} is missing or not a {getattr(kind, '__name__', 'number')}")
        return found

    for (section, key), wanted in REQUIRED.items():
        found = value(section, key, type(wanted))
        if found != wanted:
            raise StyleGesturesError(f"{path}: {section}.{key} is {json.dumps(found)}; the importer supports only "
                                     f"{json.dumps(wanted)} (the model of the authors' locomotion hparams)")
    hparams = ReferenceHparams(
        steps=value("Glow", "K", int), hidden=value("Glow", "hidden_channels", int), tau=value("Data", "seqlen", int),
        fps=float(value("Data", "framerate", (int, float))), framerate_text=str(data["Data"]["framerate"]),
        dropout=float(value("Data", "dropout", (int, float))), mirror=value("Data", "mirror", bool),
        reverse_time=value("Data", "reverse_time", bool),
    )
    for name, field in (("Glow.K", hparams.steps), ("Glow.hidden_channels", hparams.hidden), ("Data.seqlen", hparams.tau),
                        ("Data.framerate", hparams.fps)):
        if field <= 0:
            raise StyleGesturesError(f"{path}: {name} must be positive, not {field}")
    if not 0.0 <= hparams.dropout <= 1.0:
        raise StyleGesturesError(f"{path}: Data.dropout must lie in [0, 1], not {hparams.dropout}")
    return hparams


def read_checkpoint(path: str | os.PathLike) -> tuple[dict[str, torch.Tensor], int]:
    """The model's tensors and training step of a checkpoint their trainer saved."""
    path = Path(path)
    if not path.is_file():
        raise StyleGesturesError(f"{path}: no such checkpoint file")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as error:
        found = re.search(r"GLOBAL (\S+)", str(error))
        held = f"it holds a {found.group(1)}" if found else "it holds more than tensors, numbers and strings"
        raise StyleGesturesError(f"{path}: needs unpickling of objects, which is never done here ({held}); only "
                                 "tensors, numbers and strings are read") from None
    except (RuntimeError, EOFError, OSError, zipfile.BadZipFile, ValueError) as error:
        raise StyleGesturesError(f"{path}: not a PyTorch checkpoint ({str(error)[:200]})") from None
    graph = state.get("graph") if isinstance(state, dict) else None
    if not isinstance(graph, dict) or not all(isinstance(t, torch.Tensor) for t in graph.values()):
        raise StyleGesturesError(f"{path}: no 'graph' dictionary of tensors (the model's state) in this checkpoint")
    step = state.get("global_step", 0)
    return graph, step if isinstance(step, int) else 0


def _tensor(graph: dict[str, torch.Tensor], name: str, shape: tuple[int, ...], path: Path) -> torch.Tensor:
    if name not in graph:
        raise StyleGesturesError(f"{path}: tensor {name} is missing")
    tensor = graph[name].detach().float()
    if tuple(tensor.shape) != shape:
        raise StyleGesturesError(f"{path}: tensor {name} has shape {tuple(tensor.shape)}, the hparams need {shape}")
    if not torch.isfinite(tensor).all():
        raise StyleGesturesError(f"{path}: tensor {name} holds non-finite values")
    return tensor


def _lstm_layers(graph: dict[str, torch.Tensor]) -> int:
    layers = 0
    while f"flow.layers.0.f.lstm.weight_ih_l{layers}" in graph:
        layers += 1
    return layers


def convert_graph(graph: dict[str, torch.Tensor], hparams: ReferenceHparams, path: Path) -> MoGlow:
    """Our MoGlow holding their weights (in eval mode)."""
    layers = _lstm_layers(graph)
    if layers == 0:
        raise StyleGesturesError(f"{path}: tensor flow.layers.0.f.lstm.weight_ih_l0 is missing (not an LSTM MoGlow)")
    extra = sorted(name for name in graph if name.startswith(f"flow.layers.{hparams.steps}."))
    if extra:
        raise StyleGesturesError(f"{path}: tensor {extra[0]} lies beyond the hparams' K={hparams.steps} steps")
    config = MoGlowConfig(steps=hparams.steps, tau=hparams.tau, lstm_hidden=hparams.hidden, lstm_layers=layers,
                          dropout=hparams.dropout, scale_offset=SCALE_OFFSET, scale_floor=SCALE_FLOOR)
    model = MoGlow(config, POSE_DIM, CONTROL_DIM)
    split, hidden = POSE_DIM // 2, hparams.hidden
    inputs = split + model.conditioning_dim
    with torch.no_grad():
        for k in range(hparams.steps):
            actnorm, linear, coupling = model.flow.transforms[3 * k : 3 * k + 3]
            prefix = f"flow.layers.{k}"
            actnorm.bias.copy_(_tensor(graph, f"{prefix}.actnorm.bias", (1, POSE_DIM, 1), path).flatten())
            actnorm.log_scale.copy_(_tensor(graph, f"{prefix}.actnorm.logs", (1, POSE_DIM, 1), path).flatten())
            actnorm.initialized.fill_(True)
            square = (POSE_DIM, POSE_DIM)
            linear.permutation.copy_(_tensor(graph, f"{prefix}.invconv.p", square, path))
            linear.sign_s.copy_(_tensor(graph, f"{prefix}.invconv.sign_s", (POSE_DIM,), path))
            linear.lower.copy_(torch.tril(_tensor(graph, f"{prefix}.invconv.l", square, path), -1))
            linear.upper.copy_(torch.triu(_tensor(graph, f"{prefix}.invconv.u", square, path), 1))
            linear.log_s.copy_(_tensor(graph, f"{prefix}.invconv.log_s", (POSE_DIM,), path))
            for layer in range(layers):
                width = inputs if layer == 0 else hidden
                for kind, shape in (("weight_ih", (4 * hidden, width)), ("weight_hh", (4 * hidden, hidden)),
                                    ("bias_ih", (4 * hidden,)), ("bias_hh", (4 * hidden,))):
                    name = f"{kind}_l{layer}"
                    getattr(coupling.lstm, name).copy_(_tensor(graph, f"{prefix}.f.lstm.{name}", shape, path))
            outputs = 2 * (POSE_DIM - split)
            weight = _tensor(graph, f"{prefix}.f.linear.weight", (outputs, hidden), path)
            bias = _tensor(graph, f"{prefix}.f.linear.bias", (outputs,), path)
            # Theirs: rows 0, 2, 4, ... shift and 1, 3, 5, ... scale; ours: scales, then shifts.
            coupling.out.weight.copy_(torch.cat([weight[1::2], weight[0::2]]))
            coupling.out.bias.copy_(torch.cat([bias[1::2], bias[0::2]]))
    return model.eval()


def mirrored(clips: np.ndarray) -> np.ndarray:
    """Their mirroring of (clips, frames, 63 + 3) locomotion clips."""
    out = clips.copy()
    joints = out[..., :POSE_DIM].reshape(clips.shape[:2] + (len(JOINTS), 3))
    source = clips[..., :POSE_DIM].reshape(joints.shape)
    for left, right in MIRRORED_LIMBS:
        for a, b in ((left, right), (right, left)):
            joints[:, :, a : a + 4] = source[:, :, b : b + 4]
            joints[:, :, a : a + 4, 0] = -source[:, :, b : b + 4, 0]
    out[..., POSE_DIM] *= -1
    out[..., POSE_DIM + 2] *= -1
    return out


def time_reversed(clips: np.ndarray) -> np.ndarray:
    """Their time reversal: frames backwards, all control negated."""
    out = clips[:, ::-1].copy()
    out[..., POSE_DIM:] *= -1
    return out


@dataclass(frozen=True)
class ReferenceData:
    train: np.ndarray  # (clips, frames, 66) the clips they train on, before augmentation
    pose: Standardizer
    control: Standardizer
    fingerprint: str


def read_data(folder: str | os.PathLike, hparams: ReferenceHparams) -> ReferenceData:
    """Their training clips and the statistics their loader fits to them."""
    path = Path(folder) / f"all_locomotion_train_{hparams.framerate_text}fps.npz"
    try:
        with np.load(path, allow_pickle=False) as archive:
            if "clips" not in archive.files:
                raise StyleGesturesError(f"{path}: no 'clips' array (their locomotion data layout)")
            clips = archive["clips"].astype(np.float32)
    except (OSError, ValueError, zipfile.BadZipFile) as error:
        raise StyleGesturesError(f"{path}: cannot read their training data ({str(error)[:200]})") from None
    if clips.ndim != 3 or clips.shape[2] != POSE_DIM + CONTROL_DIM:
        raise StyleGesturesError(f"{path}: clips have shape {clips.shape}; their locomotion layout is "
                                 f"(clips, frames, {POSE_DIM + CONTROL_DIM})")
    if len(clips) <= VALIDATION_CLIPS:
        raise StyleGesturesError(f"{path}: {len(clips)} clips; their loader keeps the last {VALIDATION_CLIPS} for "
                                 "validation and trains on the rest, so there must be more")
    if not np.isfinite(clips).all():
        raise StyleGesturesError(f"{path}: clips hold non-finite values")
    train = clips[:-VALIDATION_CLIPS]
    augmented = np.concatenate([train, mirrored(train)]) if hparams.mirror else train
    augmented = np.concatenate([augmented, time_reversed(augmented)]) if hparams.reverse_time else augmented
    flat = augmented.reshape(-1, augmented.shape[-1]).astype(np.float64)
    var = flat.var(axis=0)
    # As sklearn's StandardScaler, which they use: constant dimensions get scale 1.
    std = np.where(var < 10 * np.finfo(np.float64).eps, 1.0, np.sqrt(var))
    mean = flat.mean(axis=0)
    fingerprint = hashlib.sha256(path.read_bytes()).hexdigest()
    return ReferenceData(train, Standardizer(mean[:POSE_DIM], std[:POSE_DIM]),
                         Standardizer(mean[POSE_DIM:], std[POSE_DIM:]), fingerprint)


def skeleton(train: np.ndarray) -> Skeleton:
    """Their joints, with offsets the mean bone vectors of the training poses."""
    joints = train[..., :POSE_DIM].reshape(-1, len(JOINTS), 3).astype(np.float64)
    offsets = np.zeros((len(JOINTS), 3))
    offsets[0] = joints[:, 0].mean(axis=0)
    for j, parent in enumerate(PARENTS[1:], start=1):
        offsets[j] = (joints[:, j] - joints[:, parent]).mean(axis=0)
    return Skeleton(JOINTS, np.array(PARENTS), offsets)


def stylegestures_control(velocities: np.ndarray, fps: float) -> np.ndarray:
    """Our path control (frames, 3: forward, sideways, yaw per second) in their layout.

    Frame i of theirs is the root's step from frame i to i+1 in the root frame at i+1
    (sideways, forward) and the yaw change from i to i+1 negated, per frame; the last
    frame repeats the one before.
    """
    if len(velocities) < 2:
        return np.zeros((len(velocities), 3))
    root = integrate(velocities, fps)
    step = to_root_frame(np.diff(root.xz, axis=0), root.yaw[1:])
    control = np.column_stack([step, -np.diff(root.yaw)])
    return np.vstack([control, control[-1:]])


def import_stylegestures(checkpoint: str | os.PathLike, hparams_path: str | os.PathLike,
                         data_folder: str | os.PathLike, out: str | os.PathLike) -> Path:
    """Convert their checkpoint; nothing is written unless every input checks out."""
    hparams = read_hparams(hparams_path)
    graph, step = read_checkpoint(checkpoint)
    model = convert_graph(graph, hparams, Path(checkpoint))
    data = read_data(data_folder, hparams)
    options = DatasetOptions(fps=hparams.fps, mirror=hparams.mirror, reverse=hparams.reverse_time)
    meta = CheckpointMeta(
        kind=model.kind,
        hyperparameters=dataclasses.asdict(model.config),
        pose_dim=POSE_DIM,
        control_dim=CONTROL_DIM,
        features={"type": "positions", "dataset_options": options.to_dict(), "control_layout": CONTROL_LAYOUT,
                  "source": f"StyleGestures checkpoint {Path(checkpoint).name}"},
        stats={"pose": data.pose.to_dict(), "control": data.control.to_dict()},
        skeleton=skeleton(data.train).to_dict(),
        data_fingerprint=data.fingerprint,
        step=step,
        code_version=code_version(),
    )
    return save_checkpoint(out, model, meta)
