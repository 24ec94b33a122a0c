"""The three rating designs a ratings table can come from, and the columns each needs.

- ``single``: one clip per page, one rating per clip (MoGlow, HVRNN). The default when a
  table has no ``design`` column, so tables written before designs existed read as before.
- ``side-by-side``: one page shows several systems' clips for the same control, each
  rated on the scale (HEMVIP / MUSHRA, as in the GENEA challenges). One row per clip;
  ``page`` groups the rows of one screen and ``position`` (1, 2, ...) says where on it
  the clip was.
- ``pairwise``: one page shows two clips and asks which is better. Two rows per page, one
  per clip, with its ``side`` (``left`` or ``right``) and the page's ``answer`` (``left``,
  ``right`` or ``none`` for no preference) repeated on both; ``strength`` (an integer from
  1) optionally says how strong a stated preference is. ``value`` and the scale columns
  are not needed.
- ``appropriateness``: a pairwise page whose two clips come from the same system, one
  made for the control the page shows and one for another control; which fits the shown
  control better? The pairwise columns, both rows naming the same system, and
  ``matched`` (true on the clip made for the shown control, false on the other) on
  each; ``strength`` is 1 (slightly) or 2 (clearly), the five levels of GENEA's question.

A page is identified by (task, participant, page): page ids may repeat across
participants (a control's name, say). One table holds one design.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import AnalysisInputError

SINGLE, SIDE_BY_SIDE, PAIRWISE = "single", "side-by-side", "pairwise"
APPROPRIATENESS = "appropriateness"
DESIGNS = (SINGLE, SIDE_BY_SIDE, PAIRWISE, APPROPRIATENESS)
PREFERENCE_DESIGNS = (PAIRWISE, APPROPRIATENESS)  # a page is answered by a preference, not rated
PAGE = ("task", "participant", "page")  # the columns that identify one screen
SIDES = ("left", "right")
NO_PREFERENCE = "none"
ANSWERS = (*SIDES, NO_PREFERENCE)

_SCALE_COLUMNS = ("value", "scale_min", "scale_max")


def table_design(ratings: pd.DataFrame) -> str:
    """The design of a ratings table: its ``design`` column, or ``single`` without one."""
    if "design" not in ratings.columns:
        return SINGLE
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


def required_columns(design: str, minimal: tuple[str, ...]) -> tuple[str, ...]:
    """The columns a table of ``design`` must have, given the single design's ``minimal``."""
    if design == SIDE_BY_SIDE:
        return (*minimal, "page")
    if design in PREFERENCE_DESIGNS:
        extra = ("matched",) if design == APPROPRIATENESS else ()
        return (*(c for c in minimal if c not in _SCALE_COLUMNS), "page", "side", "answer", *extra)
    return minimal


def needs_scale(design: str) -> bool:
    """Whether rows carry a rating on a scale (not the preference designs)."""
    return design not in PREFERENCE_DESIGNS


def validate_design_columns(df: pd.DataFrame, design: str) -> pd.DataFrame:
    """Check the page structure of a side-by-side, pairwise or appropriateness table
    (labels already checked).

    Returns the table with ``position`` and ``strength`` as integers (nullable) and
    ``side`` and ``answer`` lower-cased.
    """
    if design == SINGLE:
        return df
    df = df.copy()
    df["page"] = _labels(df["page"], "page")
    if design == SIDE_BY_SIDE:
        if "position" in df.columns:
            df["position"] = _positive_integers(df["position"], "position", allow_empty=False)
            shared = df.duplicated([*PAGE, "position"], keep=False)
            if shared.any():
                raise AnalysisInputError(
                    f"two clips share position {df.loc[shared, 'position'].iloc[0]} on page "
                    f"{_page_name(df, shared)} (first at row {_first(shared)})")
        _no_system_twice_on_a_page(df)
        return df
    for column, allowed in (("side", SIDES), ("answer", ANSWERS)):
        df[column] = df[column].astype(str).str.strip().str.lower()
        bad = ~df[column].isin(allowed)
        if bad.any():
            raise AnalysisInputError(
                f"column {column!r} must be one of {', '.join(allowed)}; row {_first(bad)} "
                f"holds {df.loc[bad, column].iloc[0]!r}")
    if "strength" in df.columns:
        df["strength"] = _positive_integers(df["strength"], "strength", allow_empty=True)
        undecided = df["strength"].notna() & (df["answer"] == NO_PREFERENCE)
        if undecided.any():
            raise AnalysisInputError(
                f"'strength' qualifies a preference, but row {_first(undecided)} gives one "
                f"with answer {NO_PREFERENCE!r}")
    pages = df.groupby(list(PAGE), sort=False)
    shape_ok = (pages["side"].transform("size") == 2) & (pages["side"].transform("nunique") == 2)
    if not shape_ok.all():
        raise AnalysisInputError(
            "a pairwise page must have exactly two rows, one on each side; page "
            f"{_page_name(df, ~shape_ok)} (first at row {_first(~shape_ok)}) does not")
    answer_ok = pages["answer"].transform("nunique") == 1
    if not answer_ok.all():
        raise AnalysisInputError(
            "the two rows of a pairwise page must carry the same answer; page "
            f"{_page_name(df, ~answer_ok)} (first at row {_first(~answer_ok)}) does not")
    if design == APPROPRIATENESS:
        return _one_system_matched_once(df)
    _no_system_twice_on_a_page(df)
    return df


def _one_system_matched_once(df: pd.DataFrame) -> pd.DataFrame:
    """An appropriateness page shows one system's clip for the shown control and its clip
    for another (``matched`` already read as booleans)."""
    pages = df.groupby(list(PAGE), sort=False)
    one_system = pages["system"].transform("nunique") == 1
    if not one_system.all():
        raise AnalysisInputError(
            "an appropriateness page shows one system twice, its matched and its mismatched clip; page "
            f"{_page_name(df, ~one_system)} (first at row {_first(~one_system)}) shows two systems")
    matched_once = pages["matched"].transform("sum") == 1
    if not matched_once.all():
        raise AnalysisInputError(
            "an appropriateness page has one matched clip (matched true) and one mismatched (false); page "
            f"{_page_name(df, ~matched_once)} (first at row {_first(~matched_once)}) does not")
    if "strength" in df.columns:
        strong = df["strength"].notna() & (df["strength"] > 2)
        if strong.any():
            raise AnalysisInputError(
                "an appropriateness answer has five levels, a preference of strength 1 (slightly) or 2 "
                f"(clearly); row {_first(strong)} gives strength {int(df.loc[strong, 'strength'].iloc[0])}")
    return df


def _no_system_twice_on_a_page(df: pd.DataFrame) -> None:
    twice = df.duplicated([*PAGE, "system"], keep=False)
    if twice.any():
        raise AnalysisInputError(
            f"system {df.loc[twice, 'system'].iloc[0]!r} appears twice on page "
            f"{_page_name(df, twice)} (first at row {_first(twice)}); a page shows each "
            "system once")


def _labels(column: pd.Series, name: str) -> pd.Series:
    text = column.astype(str).str.strip()
    empty = text.isin(["", "nan", "None"])
    if empty.any():
        raise AnalysisInputError(f"column {name!r} is empty in {int(empty.sum())} row(s), "
                                 f"first at row {_first(empty)}")
    return text


def _positive_integers(column: pd.Series, name: str, allow_empty: bool) -> pd.Series:
    text = column.astype(str).str.strip()
    empty = text.isin(["", "nan", "None", "<NA>"])
    numbers = pd.to_numeric(text.where(~empty), errors="coerce")
    not_whole = numbers.notna() & ((numbers < 1) | (numbers != np.round(numbers)))
    bad = (numbers.isna() & ~(empty & allow_empty)) | not_whole
    if bad.any():
        raise AnalysisInputError(
            f"column {name!r} must hold whole numbers from 1{' or nothing' if allow_empty else ''}; "
            f"row {_first(bad)} holds {column[bad].iloc[0]!r}")
    return numbers.astype("Int64")


def _first(mask: pd.Series) -> int:
    # 1-based data row as a spreadsheet user counts it (header excluded)
    return int(np.flatnonzero(mask.to_numpy())[0]) + 1


def _page_name(df: pd.DataFrame, mask: pd.Series) -> str:
    row = df[mask.to_numpy()].iloc[0]
    return f"{row['page']!r} of participant {row['participant']!r} in task {row['task']!r}"
