"""The page structure the designs share: what identifies a page, and the checks of its
columns that more than one design makes.

A page is identified by (task, participant, page): page ids may repeat across
participants (a control's name, say). Row numbers in messages count as a spreadsheet
user does: the first data row is 1.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import AnalysisInputError

PAGE = ("task", "participant", "page")  # the columns that identify one screen
SIDES = ("left", "right")
NO_PREFERENCE = "none"
ANSWERS = (*SIDES, NO_PREFERENCE)


def labels(column: pd.Series, name: str) -> pd.Series:
    """``column`` as stripped text; AnalysisInputError naming the first empty cell."""
    text = column.astype(str).str.strip()
    empty = text.isin(["", "nan", "None"])
    if empty.any():
        raise AnalysisInputError(f"column {name!r} is empty in {int(empty.sum())} row(s), "
                                 f"first at row {first_row(empty)}")
    return text


def positive_integers(column: pd.Series, name: str, allow_empty: bool) -> pd.Series:
    """``column`` as whole numbers from 1 (nullable where ``allow_empty``)."""
    text = column.astype(str).str.strip()
    empty = text.isin(["", "nan", "None", "<NA>"])
    numbers = pd.to_numeric(text.where(~empty), errors="coerce")
    not_whole = numbers.notna() & ((numbers < 1) | (numbers != np.round(numbers)))
    bad = (numbers.isna() & ~(empty & allow_empty)) | not_whole
    if bad.any():
        raise AnalysisInputError(
            f"column {name!r} must hold whole numbers from 1{' or nothing' if allow_empty else ''}; "
            f"row {first_row(bad)} holds {column[bad].iloc[0]!r}")
    return numbers.astype("Int64")


def every_page(df: pd.DataFrame, holds: pd.Series, rule: str, otherwise: str = "does not") -> None:
    """AnalysisInputError stating ``rule`` and naming the first page where ``holds`` is false."""
    if not holds.all():
        raise AnalysisInputError(f"{rule}; page {page_name(df, ~holds)} (first at row {first_row(~holds)}) "
                                 f"{otherwise}")


def no_system_twice_on_a_page(df: pd.DataFrame) -> None:
    twice = df.duplicated([*PAGE, "system"], keep=False)
    if twice.any():
        raise AnalysisInputError(
            f"system {df.loc[twice, 'system'].iloc[0]!r} appears twice on page "
            f"{page_name(df, twice)} (first at row {first_row(twice)}); a page shows each "
            "system once")


def first_row(mask: pd.Series) -> int:
    """The first row where ``mask`` holds, 1-based as a spreadsheet user counts it (header excluded)."""
    return int(np.flatnonzero(mask.to_numpy())[0]) + 1


def page_name(df: pd.DataFrame, mask: pd.Series) -> str:
    """The first page where ``mask`` holds, as a message names it."""
    row = df[mask.to_numpy()].iloc[0]
    return f"{row['page']!r} of participant {row['participant']!r} in task {row['task']!r}"
