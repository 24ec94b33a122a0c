"""Where the models' randomness comes from: one seed for a whole batch, or one seed per row.

``generate`` takes a ``torch.Generator`` (a batch drawn from one seed, as training and
``Generator.sample(n=...)`` use) or ``RowGenerators`` (one seed per batch row, as a study's
worker uses when it samples many controls at once). A model that draws every tensor of
noise with ``normal`` honours both, and says so with ``MotionModel.per_row_seeds``: each
row's draws then come from its own generator with exactly the shape a batch of one would
draw, so a clip sampled in a batch is the clip sampled alone with its seed.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch


class RowGenerators:
    """One ``torch.Generator`` per batch row, seeded with that row's seed."""

    def __init__(self, seeds: Sequence[int], device: str | torch.device = "cpu") -> None:
        if not seeds:
            raise ValueError("RowGenerators needs at least one seed")
        self.generators = [torch.Generator(device=device).manual_seed(int(seed)) for seed in seeds]

    def __len__(self) -> int:
        return len(self.generators)


def normal(shape: Sequence[int], generator: torch.Generator | RowGenerators | None, *,
           device: torch.device | str, dtype: torch.dtype) -> torch.Tensor:
    """Standard normal noise of ``shape`` (batch first): from ``generator``, or, for
    ``RowGenerators``, row i of shape (1, ...) from the i-th generator."""
    if not isinstance(generator, RowGenerators):
        return torch.randn(tuple(shape), generator=generator, device=device, dtype=dtype)
    batch, *rest = shape
    if batch != len(generator):
        raise ValueError(f"noise for a batch of {batch} rows, but {len(generator)} row generators")
    return torch.cat([torch.randn((1, *rest), generator=row, device=device, dtype=dtype)
                      for row in generator.generators])


__all__ = ["RowGenerators", "normal"]
