"""What every motion model shares, whatever controls it; ``path.PathModel`` and
``attribute.AttributeModel`` add the two ways of control, each with its own ``loss`` and
``generate``.

Models work on standardised features. Turning features into ``Motion`` objects
(de-standardising, integrating the control) is the job of ``generation.generator``;
loading what training needs beyond the data (HVRNN's classifiers) and the optimiser's
knobs are the job of ``generation.train``, not of the models.
"""

from __future__ import annotations

from typing import Any, ClassVar

from torch import nn


class MotionModel(nn.Module):
    """Base class of every model. Subclasses set ``kind`` and ``Config`` (a dataclass of
    the architecture and the loss).

    Constructor: ``Model(config, pose_dim, control_dim)``.
    """

    kind: ClassVar[str]
    Config: ClassVar[type]
    # The precisions ``generate`` offers for its matrix products; "float32" (the default)
    # computes in the parameters' own dtype, float32 for every trained model.
    precisions: ClassVar[tuple[str, ...]] = ("float32",)
    # Whether ``generate`` accepts ``noise.RowGenerators`` (one seed per batch row) for its
    # generator: true where every draw goes through ``noise.normal`` or nothing is drawn.
    # Without it, ``Generator.sample_batch`` samples each control alone.
    per_row_seeds: ClassVar[bool] = False

    def __init__(self, config: Any, pose_dim: int, control_dim: int) -> None:
        super().__init__()
        self.config, self.pose_dim, self.control_dim = config, pose_dim, control_dim

    def prepare(self, data: Any) -> None:
        """Take constants from the training data before training; by default none."""

    @classmethod
    def check_precision(cls, precision: str) -> None:
        if precision not in cls.precisions:
            raise ValueError(f"a {cls.kind} model samples in precision {' or '.join(cls.precisions)}, not {precision!r}")
