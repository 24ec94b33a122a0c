"""Path-controlled models (MoGlow and its RNN and VAE baselines): control in, poses out.

They learn from windows of standardised poses (batch, frames, pose_dim) and control
(batch, frames, control_dim), as ``MotionDataset.windows`` returns them, and generate
poses for any control sequence.
"""

from __future__ import annotations

import torch

from .motion_model import MotionModel


class PathModel(MotionModel):
    """Base class of models that follow a control path."""

    # How many past poses the model needs before it can continue a sequence (0: none).
    context_frames: int = 0

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        """The training objective on a batch of windows (a scalar to minimise) and named metrics."""
        raise NotImplementedError

    @torch.no_grad()
    def generate(
        self,
        control: torch.Tensor,
        context: torch.Tensor | None,
        temperature: float = 1.0,
        generator: torch.Generator | None = None,
        precision: str = "float32",
    ) -> torch.Tensor:
        """Poses (batch, frames, pose_dim) for control (batch, frames, control_dim).

        ``context`` (batch, context_frames, pose_dim) seeds autoregressive models: they
        are the poses of the first ``context_frames`` frames, whose control is the start
        of ``control``; the output repeats them and continues. Models without context
        ignore it. Randomness comes only from ``generator``, so a seed reproduces a
        sample. ``precision`` is one of the class's ``precisions``.
        """
        raise NotImplementedError
