"""The least data each result needs, in one place, and the words that say so.

A mixed model fitted to a handful of ratings, or a bootstrap over one or two participants,
still returns numbers: standard errors of 1e5, odds ratios of 1e-11, intervals of zero
width. Below these minimums the monitor, the report and the command line say "too few
ratings" (and how many there are, and how many are needed) instead of showing them.

- ``MODEL_MIN_PARTICIPANTS`` and ``MODEL_MIN_RATINGS_PER_SYSTEM``: the rater- and
  clip-aware models (crossed linear mixed model, cumulative link mixed model) and the
  participant mixed model need participants to estimate a participant variance from, and
  every system of a cell needs ratings to estimate its effect from.
- ``BOOTSTRAP_MIN_PARTICIPANTS``: a bootstrap over participants draws from that many
  participants at least; from one it can only return that participant's mean.
- ``INTERVAL_FEW_PARTICIPANTS``: an interval from fewer participants than this is shown,
  with a warning: its width rests on very few raters (ratings of one participant are not
  independent), so it is less certain than it looks.
"""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from analysis.stats.anova import CELL, iter_cells

MODEL_MIN_PARTICIPANTS = 5
MODEL_MIN_RATINGS_PER_SYSTEM = 5
BOOTSTRAP_MIN_PARTICIPANTS = 5
INTERVAL_FEW_PARTICIPANTS = 10


def _counted(n: int, word: str) -> str:
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def too_few_for_model(data: pd.DataFrame, between: str = "system", participant: str = "participant") -> str:
    """Why ``data`` (one cell's ratings) is too little for a model, or "" when it is enough."""
    participants = data[participant].nunique()
    per_system = data.groupby(between).size()
    fewest = int(per_system.min()) if len(per_system) else 0
    if participants >= MODEL_MIN_PARTICIPANTS and fewest >= MODEL_MIN_RATINGS_PER_SYSTEM:
        return ""
    short_system = fewest < MODEL_MIN_RATINGS_PER_SYSTEM and len(per_system)
    least = f" ({per_system.idxmin()} has {fewest})" if short_system else ""
    return (f"too few ratings: {len(data)} from {_counted(participants, 'participant')}{least}; a model needs at "
            f"least {MODEL_MIN_PARTICIPANTS} participants and {MODEL_MIN_RATINGS_PER_SYSTEM} ratings per system")


def too_few_for_bootstrap(participants: int) -> str:
    """Why a bootstrap over ``participants`` participants is not run, or "" when it is."""
    if participants >= BOOTSTRAP_MIN_PARTICIPANTS:
        return ""
    return (f"too few ratings: from {_counted(participants, 'participant')}; a bootstrap interval needs at least "
            f"{BOOTSTRAP_MIN_PARTICIPANTS} participants")


def few_participants_warning(participants: int) -> str:
    """The warning an interval from ``participants`` participants carries, or "" when none."""
    if participants >= INTERVAL_FEW_PARTICIPANTS:
        return ""
    return (f"from {_counted(participants, 'participant')} only (fewer than {INTERVAL_FEW_PARTICIPANTS}): "
            "the interval is less certain than it looks")


def cells_for_models(data: pd.DataFrame, what: str, groupby: Sequence[str] = CELL) -> tuple[pd.DataFrame, list[str]]:
    """The cells of ``data`` with enough ratings for a model, and a note for each of the
    others naming ``what`` was not fitted there."""
    keep, notes = [], []
    for key, frame in iter_cells(data, groupby):
        reason = too_few_for_model(frame)
        if reason:
            notes.append(f"No {what} for {' · '.join(map(str, key.values())) or 'all ratings'}: {reason}.")
        else:
            keep.append(frame)
    return (pd.concat(keep) if keep else data.iloc[:0]), notes


def with_participant_warnings(table: pd.DataFrame, ratings: pd.DataFrame,
                              keys: Sequence[str] = (*CELL, "system")) -> pd.DataFrame:
    """``table`` (a row per ``keys``: cell and system, or cell and pair, with an interval)
    with the columns ``participants`` (who gave the row's ratings or pages, by the same
    keys in ``ratings``) and ``warning`` (`few_participants_warning`)."""
    keys = list(keys)
    counts = ratings.groupby(keys)["participant"].nunique().rename("participants").reset_index()
    joined = table.drop(columns=["participants", "warning"], errors="ignore").merge(counts, on=keys, how="left")
    joined["participants"] = joined["participants"].fillna(0).astype(int)
    joined["warning"] = [few_participants_warning(n) for n in joined["participants"]]
    return joined


def participant_warning_notes(table: pd.DataFrame, groupby: Sequence[str] = CELL, between: str = "system") -> list[str]:
    """A note per row of ``with_participant_warnings``'s table that carries a warning."""
    return [f"The interval of {row[between]} in {' · '.join(str(row[c]) for c in groupby)} is "
            f"{row['warning']}." for _, row in table.iterrows() if row["warning"]]
