"""What every motion model provides, so training, sampling and the study app treat all alike.

Models work on standardised features: poses (batch, frames, pose_dim) and control
(batch, frames, control_dim), as returned by ``MotionDataset.windows``. Turning features
into ``Motion`` objects (de-standardising, integrating the control) is the job of
``generation.generator``, not of the models.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import torch
from torch import nn


class MotionModel(nn.Module):
    """Base class of every model. Subclasses set ``kind`` and ``Config`` (a dataclass).

    Constructor: ``Model(config, pose_dim, control_dim)``.
    """

    kind: ClassVar[str]
    Config: ClassVar[type]
    # How many past poses the model needs before it can continue a sequence (0: none).
    context_frames: int = 0
    # The precisions ``generate`` offers for its matrix products; "float32" (the default)
    # computes in the parameters' own dtype, float32 for every trained model.
    precisions: ClassVar[tuple[str, ...]] = ("float32",)

    def __init__(self, config: Any, pose_dim: int, control_dim: int) -> None:
        super().__init__()
        self.config, self.pose_dim, self.control_dim = config, pose_dim, control_dim

    def loss(self, pose: torch.Tensor, control: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        """The training objective on a batch (a scalar to minimise) and named metrics."""
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

    @classmethod
    def check_precision(cls, precision: str) -> None:
        if precision not in cls.precisions:
            raise ValueError(f"a {cls.kind} model samples in precision {' or '.join(cls.precisions)}, not {precision!r}")

    def hyperparameters(self) -> dict:
        return dataclasses.asdict(self.config)
