"""The power table of a table's kept ratings: `analysis.stats.power.more_ratings_for_power`
with the table's design found from the table (`analysis.designs.design_of`)."""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from analysis.designs import design_of
from analysis.stats import power as closed_forms
from analysis.stats.anova import CELL


def more_ratings_for_power(kept: pd.DataFrame, alpha: float = 0.05, power: float = 0.8,
                           groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """Per cell and pair of systems, the ratings (or pages) needed for ``power`` at ``alpha``
    (columns: `analysis.stats.power.more_ratings_for_power`)."""
    return closed_forms.more_ratings_for_power(kept, design_of(kept), alpha, power, groupby)
