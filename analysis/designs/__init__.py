"""The rating designs a ratings table can come from: one object per design, asked by the
rest of the analysis for everything that differs between designs (`base.RatingDesign`).

- ``single`` (`single.py`): one clip per page, one rating per clip (MoGlow, HVRNN). The
  default when a table has no ``design`` column, so tables written before designs existed
  read as before.
- ``side-by-side`` (`side_by_side.py`): one page shows several systems' clips for the
  same control, each rated on the scale (HEMVIP / MUSHRA, as in the GENEA challenges).
  One row per clip; ``page`` groups the rows of one screen and ``position`` (1, 2, ...)
  says where on it the clip was.
- ``pairwise`` (`pairwise.py`): one page shows two clips and asks which is better. Two
  rows per page, one per clip, with its ``side`` (``left`` or ``right``) and the page's
  ``answer`` (``left``, ``right`` or ``none`` for no preference) repeated on both;
  ``strength`` (an integer from 1) optionally says how strong a stated preference is.
  ``value`` and the scale columns are not needed.
- ``appropriateness`` (`appropriateness.py`): a pairwise page whose two clips come from
  the same system, one made for the control the page shows and one for another control;
  which fits the shown control better? The pairwise columns, both rows naming the same
  system, and ``matched`` (true on the clip made for the shown control, false on the
  other) on each; ``strength`` is 1 (slightly) or 2 (clearly), the five levels of GENEA's
  question.

A page is identified by (task, participant, page) (`analysis.pages`). One table holds one
design.

A design is a class named here as "module:Class" and imported when first asked for, so
that the study app can ask for the names without importing the statistics and the
plots. The design modules build on the statistics, the exclusion rules and the reports,
which take the design object as an argument and never ask this registry; only the
entry points above (`analysis.ratings`, `analysis.cli`) look a table's design up. Adding a
design is its module and one entry in `DESIGNS` (docs/architecture.md).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from functools import cache
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from analysis.pages import ANSWERS, NO_PREFERENCE, PAGE, SIDES
from analysis.errors import AnalysisInputError

if TYPE_CHECKING:
    from analysis.designs.base import RatingDesign

DESIGNS: dict[str, str] = {
    "single": "analysis.designs.single:Single",
    "side-by-side": "analysis.designs.side_by_side:SideBySide",
    "pairwise": "analysis.designs.pairwise:Pairwise",
    "appropriateness": "analysis.designs.appropriateness:Appropriateness",
}
DEFAULT = "single"  # the design of a table without a design column

__all__ = ["ANSWERS", "DEFAULT", "DESIGNS", "NO_PREFERENCE", "PAGE", "SIDES", "design_named", "design_of",
           "designs_where", "table_design"]


def table_design(ratings: pd.DataFrame) -> str:
    """The design's name of a ratings table: its ``design`` column, or ``single`` without one."""
    if "design" not in ratings.columns:
        return DEFAULT
    if ratings.empty:
        raise AnalysisInputError("ratings table has no rows")
    names = ratings["design"].astype(str).str.strip()
    unknown = ~names.isin(DESIGNS)
    if unknown.any():
        row = int(np.flatnonzero(unknown.to_numpy())[0]) + 1
        raise AnalysisInputError(
            f"column 'design' must be one of {', '.join(DESIGNS)}; row {row} holds "
            f"{ratings['design'].iloc[row - 1]!r}")
    found = names.unique()
    if len(found) > 1:
        raise AnalysisInputError(
            f"column 'design' mixes {', '.join(sorted(found))}; analyse each design's "
            "ratings as a table of its own")
    return str(found[0])


def design_of(ratings: pd.DataFrame) -> RatingDesign:
    """The design object of a ratings table (see `table_design`)."""
    return design_named(table_design(ratings))


@cache
def design_named(name: str) -> RatingDesign:
    """The design called ``name``; KeyError naming the known ones for any other."""
    if name not in DESIGNS:
        raise KeyError(f"unknown rating design {name!r}; known: {', '.join(DESIGNS)}")
    module, _, cls = DESIGNS[name].partition(":")
    return getattr(importlib.import_module(module), cls)()


def designs_where(holds: Callable[[RatingDesign], bool]) -> list[str]:
    """The names of the designs for which ``holds``, in the order of `DESIGNS`."""
    return [name for name in DESIGNS if holds(design_named(name))]
