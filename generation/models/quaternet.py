"""A QuaterNet-style model (Pavllo et al., 2018), an attribute-controlled baseline of Ghorbani et al.'s Table 2.

A two-layer GRU (2 × 1000) steps through the sequence as ``recurrent.RecurrentBaseline``
describes; its linear output is normalised to unit quaternions. It learns by squared
error of the joint positions that forward kinematics makes of the predicted rotations
(relative to the hips, in units of the skeleton's size) plus the squared error of the
root values. Positions do not care about a quaternion's sign, so neither does this loss.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torch import nn

from ..motion.features import ROOT_DIMS
from .parts.kinematics import forward_kinematics
from .parts.rotations import quat_to_matrix
from .recurrent import RecurrentBaseline, RecurrentConfig


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
        local = quat_to_matrix(features[..., ROOT_DIMS:].unflatten(-1, (self.joints, 4)))
        hips = torch.eye(3, device=local.device, dtype=local.dtype).expand(*local.shape[:-3], 1, 3, 3)
        return forward_kinematics(torch.cat([hips, local], -3), self.offsets, self.parents.tolist()) / self.size

    def frame_error(self, predicted: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        root = ((predicted[..., :ROOT_DIMS] - target[..., :ROOT_DIMS]) ** 2).mean(-1)
        positions = (self.positions(predicted) - self.positions(target)).pow(2).sum(-1).mean(-1)
        return root + self.config.position_weight * positions


