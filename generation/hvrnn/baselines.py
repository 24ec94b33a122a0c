"""The attribute-controlled baselines of Ghorbani et al.'s Table 2: ERD and a QuaterNet-style model.

Both step through a sequence frame by frame: the input at frame t is frame t − 1 (a
learned start frame before the first) with the one-hot action and style codes, and the
output is frame t; training feeds the real previous frame (teacher forcing), generation
feeds back its own output. Their only randomness is the recurrent network's initial
state, drawn from a learned Gaussian of each (action, style) pair
(``initial_state.LabelledInitialState``, whose KL term is weighted by ``initial_kl_weight``).

* ERD (Fragkiadaki et al., 2015): an encoder MLP, a two-layer LSTM and a decoder MLP;
  paper sizes 500-500, 2 × 1000 and 500-100. It learns by squared error on the
  features (standardised root values, unit quaternions).
* QuaterNet-style (Pavllo et al., 2018): a two-layer GRU (2 × 1000) whose linear output
  is normalised to unit quaternions; it learns by squared error of the joint positions
  that forward kinematics makes of the predicted rotations (relative to the hips, in
  units of the skeleton's size) plus the squared error of the root values. Positions
  do not care about a quaternion's sign, so neither does this loss.

Input and target quaternions are flipped into the hemisphere of the training average
(q and −q are one rotation), so the squared errors compare like with like.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

import torch
from torch import nn

from ..models.attribute import AttributeModel
from .data import ROOT_DIMS
from .kinematics import forward_kinematics
from .model import mlp, random_crop
from .initial_state import LabelledInitialState
from .rotation_losses import align_quaternions, masked_mean, normalize_quaternion, quaternion_to_matrix


class RecurrentBaseline(AttributeModel):
    """What ERD and QuaterNet share; subclasses build ``recurrent`` (an ``nn.LSTM`` or
    ``nn.GRU``, batch first) and define ``run`` and ``frame_error``."""

    state_parts: ClassVar[int]  # 2 for an LSTM's (h, c), 1 for a GRU's h

    def __init__(self, config: Any, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        if pose_dim <= ROOT_DIMS or (pose_dim - ROOT_DIMS) % 4:
            raise ValueError(f"a {self.kind} model reads six root values and a quaternion per joint; "
                             f"pose_dim {pose_dim} is not 6 + 4k")
        self.joints = (pose_dim - ROOT_DIMS) // 4
        combinations = len(self.actions) * len(self.styles)
        size = self.state_parts * config.layers * config.hidden
        self.initial = LabelledInitialState(combinations, size)
        self.start = nn.Parameter(torch.zeros(pose_dim))  # the input before the first frame
        # Set by prepare(): each joint's sign reference.
        self.register_buffer("reference", torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(self.joints, 1))

    def prepare(self, data: Any) -> None:
        self.reference.copy_(torch.as_tensor(data.quaternion_reference()))

    def align(self, features: torch.Tensor) -> torch.Tensor:
        """Features with every quaternion flipped into the hemisphere of ``reference``."""
        return align_quaternions(features, self.reference, ROOT_DIMS)

    def normalise(self, raw: torch.Tensor) -> torch.Tensor:
        """Network outputs with each joint's quaternion scaled to unit length."""
        quats = normalize_quaternion(raw[..., ROOT_DIMS:].unflatten(-1, (self.joints, 4)))
        return torch.cat([raw[..., :ROOT_DIMS], quats.flatten(-2)], -1)

    def initial_state(self, action: torch.Tensor, style: torch.Tensor, temperature: float,
                      generator: torch.Generator | None = None) -> tuple[Any, torch.Tensor]:
        """The recurrent state drawn from each pair's Gaussian, and its KL from N(0, I) (batch,)."""
        sample, kl = self.initial(self.combination(action, style), temperature, generator)
        layers = sample.unflatten(-1, (self.state_parts, self.config.layers, self.config.hidden))
        states = tuple(layers[:, i].transpose(0, 1).contiguous() for i in range(self.state_parts))
        return (states if self.state_parts == 2 else states[0]), kl

    def run(self, inputs: torch.Tensor, codes: torch.Tensor, state: Any) -> tuple[torch.Tensor, Any]:
        """Raw outputs (batch, frames, pose_dim) for previous frames and one-hot codes (batch, codes)."""
        raise NotImplementedError

    @staticmethod
    def with_codes(inputs: torch.Tensor, codes: torch.Tensor) -> torch.Tensor:
        """Each frame's input followed by its sequence's one-hot codes."""
        return torch.cat([inputs, codes.unsqueeze(1).expand(-1, inputs.shape[1], -1)], -1)

    def frame_error(self, predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """The training error of each frame (batch, frames) of normalised predictions."""
        raise NotImplementedError

    def loss(self, pose: torch.Tensor, mask: torch.Tensor, action: torch.Tensor,  # type: ignore[override]
             style: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        if self.training and 0 < self.config.crop_frames < pose.shape[1]:
            pose, mask = random_crop(pose, mask, self.config.crop_frames)
        target = self.align(pose)
        previous = torch.cat([self.start.expand(len(pose), 1, -1), target[:, :-1]], 1)
        state, kl = self.initial_state(action, style, 1.0)
        predicted = self.normalise(self.run(previous, self.one_hot(action, style), state)[0])
        reconstruction = masked_mean(self.frame_error(predicted, target), mask)
        total = reconstruction + self.config.initial_kl_weight * kl.mean()
        return total, {"reconstruction": float(reconstruction.detach()), "initial_kl": float(kl.mean().detach())}

    @torch.no_grad()
    def generate_from_labels(self, action: torch.Tensor, style: torch.Tensor, frames: int,
                             temperature: float = 1.0, generator: torch.Generator | None = None) -> torch.Tensor:
        """Frame by frame from a sampled initial state; ``temperature`` scales its spread."""
        if frames < 1:
            raise ValueError(f"frames must be at least 1, got {frames}")
        device = self.start.device
        action, style = action.to(device), style.to(device)
        codes = self.one_hot(action, style)
        state, _ = self.initial_state(action, style, temperature, generator)
        frame = self.start.expand(len(action), 1, -1)
        out = []
        for _ in range(frames):
            raw, state = self.run(frame, codes, state)
            frame = self.normalise(raw)
            out.append(frame)
        return torch.cat(out, 1)


@dataclass
class RecurrentConfig:
    """What both baselines' configurations hold."""

    hidden: int = 1000
    layers: int = 2
    initial_kl_weight: float = 1e-3
    crop_frames: int = 0  # train on random crops of this many frames (0: whole sequences)
    # Read by the shared training loop.
    learning_rate: float = 1e-3
    grad_clip: float = 0.1
    batch_size: int = 32
    actions: tuple[str, ...] = ()
    styles: tuple[str, ...] = ()


@dataclass
class ERDConfig(RecurrentConfig):
    """Hyperparameters; the defaults are ERD's sizes (the ``paper`` preset)."""

    encoder: tuple[int, ...] = (500, 500)
    decoder: tuple[int, ...] = (500, 100)


class ERD(RecurrentBaseline):
    kind = "erd"
    Config = ERDConfig
    state_parts = 2

    def __init__(self, config: ERDConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.encoder = nn.Sequential(mlp([pose_dim + control_dim, *config.encoder]), nn.ReLU())
        self.recurrent = nn.LSTM(config.encoder[-1], config.hidden, config.layers, batch_first=True)
        self.decoder = mlp([config.hidden, *config.decoder, pose_dim])

    def run(self, inputs: torch.Tensor, codes: torch.Tensor, state: Any) -> tuple[torch.Tensor, Any]:
        h, state = self.recurrent(self.encoder(self.with_codes(inputs, codes)), state)
        return self.decoder(h), state

    def frame_error(self, predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        return ((predicted - target) ** 2).mean(-1)


@dataclass
class QuaterNetConfig(RecurrentConfig):
    """Hyperparameters; the defaults are QuaterNet's sizes (the ``paper`` preset)."""

    position_weight: float = 1.0  # on the squared joint-position error, in skeleton sizes


class QuaterNet(RecurrentBaseline):
    kind = "quaternet"
    Config = QuaterNetConfig
    state_parts = 1

    def __init__(self, config: QuaterNetConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.recurrent = nn.GRU(pose_dim + control_dim, config.hidden, config.layers, batch_first=True)
        self.output = nn.Linear(config.hidden, pose_dim)
        # The body skeleton, set by prepare(): the hips (joint 0) then the rotated joints.
        self.register_buffer("offsets", torch.zeros(self.joints + 1, 3))
        self.register_buffer("parents", torch.full((self.joints + 1,), -1, dtype=torch.long))
        self.register_buffer("size", torch.ones(()))  # RMS distance of the rest joints from the hips

    def prepare(self, data: Any) -> None:
        super().prepare(data)
        skeleton, spec = data.dataset.skeleton, data.dataset.angle_spec
        if spec.hips != 0 or list(spec.joints) != list(range(1, skeleton.n_joints)) or skeleton.n_joints != self.joints + 1:
            raise ValueError(f"QuaterNet needs a body skeleton rooted at the hips with every other joint rotated; "
                             f"this one has {skeleton.n_joints} joints, hips {spec.hips}, {len(spec.joints)} rotated")
        self.offsets.copy_(torch.as_tensor(skeleton.offsets, dtype=torch.float32))
        self.offsets[0] = 0.0  # positions relative to the hips
        self.parents.copy_(torch.as_tensor(skeleton.parents, dtype=torch.long))
        rest = forward_kinematics(torch.eye(3).expand(self.joints + 1, 3, 3), self.offsets, self.parents.tolist())
        self.size.copy_(rest.pow(2).sum(-1).mean().sqrt())

    def run(self, inputs: torch.Tensor, codes: torch.Tensor, state: Any) -> tuple[torch.Tensor, Any]:
        h, state = self.recurrent(self.with_codes(inputs, codes), state)
        return self.output(h), state

    def positions(self, features: torch.Tensor) -> torch.Tensor:
        """Joint positions relative to the hips (..., joints + 1, 3), in skeleton sizes."""
        local = quaternion_to_matrix(features[..., ROOT_DIMS:].unflatten(-1, (self.joints, 4)))
        hips = torch.eye(3, device=local.device, dtype=local.dtype).expand(*local.shape[:-3], 1, 3, 3)
        return forward_kinematics(torch.cat([hips, local], -3), self.offsets, self.parents.tolist()) / self.size

    def frame_error(self, predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        root = ((predicted[..., :ROOT_DIMS] - target[..., :ROOT_DIMS]) ** 2).mean(-1)
        positions = (self.positions(predicted) - self.positions(target)).pow(2).sum(-1).mean(-1)
        return root + self.config.position_weight * positions


# The cpu presets: under a tenth of the parameters, and 60-frame crops as HVRNN's cpu preset.
PRESETS = {
    "erd": {"paper": ERDConfig(),
            "cpu": ERDConfig(encoder=(128, 128), hidden=256, decoder=(128, 64), batch_size=16, crop_frames=60)},
    "quaternet": {"paper": QuaterNetConfig(), "cpu": QuaterNetConfig(hidden=256, batch_size=16, crop_frames=60)},
}


def _preset(kind: str, name: str) -> Any:
    if name not in PRESETS[kind]:
        raise ValueError(f"unknown {kind} preset {name!r}; use one of {sorted(PRESETS[kind])}")
    return dataclasses.replace(PRESETS[kind][name])


def erd_preset(name: str) -> ERDConfig:
    """An ERD preset by name: ``paper`` or ``cpu``."""
    return _preset("erd", name)


def quaternet_preset(name: str) -> QuaterNetConfig:
    """A QuaterNet preset by name: ``paper`` or ``cpu``."""
    return _preset("quaternet", name)
