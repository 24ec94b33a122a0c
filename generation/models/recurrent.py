"""What the attribute-controlled baselines of Ghorbani et al.'s Table 2 share (``erd``,
``quaternet``): a recurrent network stepping through a sequence frame by frame.

The input at frame t is frame t − 1 (a learned start frame before the first) with the
one-hot action and style codes, and the output is frame t; training feeds the real
previous frame (teacher forcing), generation feeds back its own output. Their only
randomness is the recurrent network's initial state, drawn from a learned Gaussian of
each (action, style) pair (``initial_state.LabelledInitialState``, whose KL term is
weighted by ``initial_kl_weight``).

Input and target quaternions are flipped into the hemisphere of the training average
(q and −q are one rotation), so the squared errors compare like with like.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import torch
from torch import nn

from ..motion.features import ROOT_DIMS
from .attribute import AttributeModel
from .parts.initial_state import LabelledInitialState
from .parts.layers import random_crop
from .parts.losses import masked_mean
from .parts.noise import RowGenerators
from .parts.rotations import align_quaternions, normalize_quaternion


class RecurrentBaseline(AttributeModel):
    """What ERD and QuaterNet share; subclasses build ``recurrent`` (an ``nn.LSTM`` or
    ``nn.GRU``, batch first) and define ``run`` and ``frame_error``."""

    state_parts: ClassVar[int]  # 2 for an LSTM's (h, c), 1 for a GRU's h
    per_row_seeds = True  # the initial state is the only draw

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
                      generator: torch.Generator | RowGenerators | None = None) -> tuple[Any, torch.Tensor]:
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

    def loss(self, pose: torch.Tensor, mask: torch.Tensor, action: torch.Tensor,
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
    def generate(self, action: torch.Tensor, style: torch.Tensor, frames: int,
                 temperature: float = 1.0, generator: torch.Generator | RowGenerators | None = None) -> torch.Tensor:
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
    actions: tuple[str, ...] = ()
    styles: tuple[str, ...] = ()


