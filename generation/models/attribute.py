"""What attribute-controlled models (HVRNN, ERD, QuaterNet) share: labels in, angle features out.

They learn from padded angle sequences with a mask and an action and a style label per
sequence (``generation.hvrnn.data``), and generate sequences of any length for a pair of
labels. Their configuration dataclass carries the label vocabularies, ``actions`` and
``styles`` (filled from the training data before the model is built), so a checkpoint
knows which labels it accepts; ``control_dim`` is the length of the two one-hot codes.

The training loop calls ``loss(pose, mask, action, style)`` on batches of standardised
features (``standardization`` says which dimensions are standardised), and
``prepare(data)`` once before training, for constants taken from the training data;
``generate(action, style, frames)`` makes standardised features for label indices.
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch
from torch.nn import functional as F

from .motion_model import MotionModel


class AttributeModel(MotionModel):
    """Base class of models controlled by action and style labels."""

    # Which standardiser of ``AttributeData`` the features use: "root" (the six root
    # values; quaternions stay unit quaternions) or "all".
    standardization: ClassVar[str] = "root"

    def __init__(self, config: Any, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        self.actions, self.styles = tuple(config.actions), tuple(config.styles)
        if not self.actions or not self.styles:
            raise ValueError(f"a {self.kind} model needs its label vocabularies (config.actions and config.styles), "
                             "which training fills in from the data")
        if control_dim != len(self.actions) + len(self.styles):
            raise ValueError(f"control_dim {control_dim} is not the number of actions ({len(self.actions)}) "
                             f"plus styles ({len(self.styles)})")

    def label_indices(self, action: str, style: str) -> tuple[int, int]:
        """The indices of an action and a style (ValueError naming the known labels)."""
        for name, names, kind in ((action, self.actions, "action"), (style, self.styles, "style")):
            if name not in names:
                raise ValueError(f"unknown {kind} {name!r}; this model knows the {kind}s {', '.join(names)}")
        return self.actions.index(action), self.styles.index(style)

    def one_hot(self, action: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """(batch, actions + styles): the two labels of each sequence as concatenated one-hot codes."""
        return torch.cat([F.one_hot(action, len(self.actions)), F.one_hot(style, len(self.styles))], -1).float()

    def combination(self, action: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """The index of each (action, style) pair, for per-combination parameters."""
        return action * len(self.styles) + style

    def loss(self, pose: torch.Tensor, mask: torch.Tensor, action: torch.Tensor,
             style: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        """The training objective on padded sequences (batch, frames, pose_dim) with their
        mask (batch, frames) and label indices (batch,)."""
        raise NotImplementedError

    @torch.no_grad()
    def generate(self, action: torch.Tensor, style: torch.Tensor, frames: int,
                 temperature: float = 1.0, generator: torch.Generator | None = None) -> torch.Tensor:
        """Standardised features (batch, frames, pose_dim) for label indices (batch,);
        randomness only from ``generator``, so a seed reproduces a sample."""
        raise NotImplementedError
