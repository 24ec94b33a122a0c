"""Reading and validating a ratings table: one row per rating given by one participant.

This is the contract: ``COLUMNS`` below declares every column the analysis reads or the app writes, its
type and what it means, and ``docs/reference/ratings-schema.md`` is written from it
(``make docs-reference``), with the designs that require each column
(``analysis.designs``) and those whose tables the study app writes it in
(``studyapp.researchers.results.export``). ``docs/ratings-schema.md`` explains the designs,
the exclusion rules and what is refused.

A table of the single design needs ``REQUIRED_COLUMNS``; side-by-side, pairwise and
appropriateness tables carry a ``design`` column and the page structure their design
objects check (`analysis.designs`), and pairwise and appropriateness tables need no
``value`` or scale columns. Without a ``design`` column a table is ``single``, unless its
columns are another design's: one lacking ``value`` and the scale columns but with that
design's columns, or one whose ``page`` is shared by several rows (a single page shows one
clip), is refused and told to add the ``design`` column. Whether a rating was given before
its clip finished playing is read from the first of ``answered_before_end``;
``played_until_s`` with ``clip_duration_s``; ``shown_at`` and ``answered_at`` with
``clip_duration_s`` that the table has; with none of them the early-answer rule cannot be
applied and the report says so. Any other column is carried through untouched.

A GENEA leaderboard vote file (one row per vote: ``user, input_code, model_a, model_b,
winner, is_strong``, ...) is recognised by its header and read as a pairwise or
appropriateness table (`analysis.ratings.genea_files`).
"""

from __future__ import annotations

import csv
import io
import os
from typing import IO, TYPE_CHECKING, NamedTuple

import numpy as np
import pandas as pd

from analysis.designs import DEFAULT, DESIGNS, PAGE, design_named, design_of
from analysis.errors import AnalysisInputError
from analysis.ratings.genea_files import VOTE_COLUMNS, genea_ratings, is_genea_header

if TYPE_CHECKING:
    from analysis.designs.base import RatingDesign


class Column(NamedTuple):
    """One column of a ratings table as the reference states it."""

    name: str
    type: str
    meaning: str


COLUMNS: tuple[Column, ...] = (
    Column("design", "text", "how the ratings were collected: `side-by-side`, `pairwise` or `appropriateness` "
                             "(a table of those designs says so here), or `single`, the design of a table "
                             "without the column; one table holds one design"),
    Column("participant", "text", "anonymous participant id"),
    Column("page", "text", "one screen of one participant: rows with the same task, participant and page were "
                           "answered together (page ids may repeat across participants)"),
    Column("position", "whole number from 1", "side-by-side: where on the page the clip was (1..K)"),
    Column("system", "text", "the system that produced the clip; `NAT` is natural motion (a compared system), "
                             "`BAD` an attention-check clip (not compared); both names are options "
                             "(`--natural`, `--attention`)"),
    Column("stimulus", "text", "clip id, unique within a task"),
    Column("clip", "text, or empty", "the clip's motion file stem, as the study app's motion export names it "
                                     "(`<control id>`, in its system's folder; `stimulus` is the opaque token "
                                     "of its video): `report --motion` matches a rated clip to its metrics by it "
                                     "for the per-clip correlation, by `stimulus` where it is absent or empty"),
    Column("task", "text", "one block of columns in Table 2 (e.g. `human`, `dog`); each task uses one scale. "
                           "Default `all`"),
    Column("control_class", "text", "e.g. `held-out` or `synthetic` control: the second level of Table 2's "
                                    "columns. Default `all`"),
    Column("side", "`left` or `right`", "pairwise and appropriateness: the side of the page the clip was on"),
    Column("matched", "true/false", "appropriateness: `true` on the clip made for the control the page shows, "
                                    "`false` on the other"),
    Column("answer", "`left`, `right` or `none`", "pairwise and appropriateness: the preferred side, `none` for "
                                                  "no preference; the same on both rows of a page"),
    Column("strength", "whole number from 1, or empty", "how much better the preferred clip is, from 1 (slightly) "
                                                        "to the study's number of degrees (GENEA's five levels: 1 "
                                                        "slightly, 2 clearly); empty for `none` and a plain answer"),
    Column("juiceOptions", "GENEA's options, or empty", "pairwise and side-by-side: the reasons ticked for the "
                                                        "page's answer, as GENEA's battles file holds them (a dict "
                                                        "of lists of options, `{}` for none; the study app's under "
                                                        "`reasons`), the same on every row of the page"),
    Column("juiceOtherReason", "text, or empty", "pairwise and side-by-side: the participant's own words under "
                                                 "\"Other\" (counted as the reason `Other`)"),
    Column("shown_control", "text", "appropriateness: the control the page shows"),
    Column("made_for", "text", "appropriateness: the control the clip was made for"),
    Column("value", "integer", "the rating, `scale_min <= value <= scale_max`"),
    Column("scale_min", "integer", "lowest point of the scale (MoGlow: 1)"),
    Column("scale_max", "integer", "highest point of the scale (MoGlow: 5)"),
    Column("clip_duration_s", "seconds", "the clip's length"),
    Column("shown_at", "ISO 8601 time or seconds", "when the clip was shown, by the server's clock (in a "
                                                   "single-clip study: when the server answered the rating "
                                                   "before, whose redirect leads to the clip, or sent the clip's "
                                                   "page where nothing led there)"),
    Column("answered_at", "ISO 8601 time or seconds", "when the rating arrived, by the server's clock"),
    Column("client_started_s", "seconds, or empty", "by the browser: seconds after the clip's page was shown "
                                                    "when the video started (empty where it did not report it)"),
    Column("client_ended_s", "seconds, or empty", "by the browser: when the video ended"),
    Column("client_answered_s", "seconds, or empty", "by the browser: when the answer was given"),
    Column("played_until_s", "seconds, or empty", "the video's position at the answer, by the browser; early if "
                                                  "below `clip_duration_s` (used without `answered_before_end`)"),
    Column("answered_before_end", "true/false", "the rating was given before the clip had finished playing"),
    Column("excluded_participant", "true/false", "the app's exclusion of the participant as it was when their "
                                                 "answers arrived; analysis recomputes it from the rules, reports "
                                                 "a disagreement and keeps the app's as "
                                                 "`app_excluded_participant`"),
    Column("discarded_early", "true/false", "the app's early-answer discard; analysis recomputes it and keeps the "
                                            "app's as `app_discarded_early`"),
    Column("exclusion_reason", "text", "why the participant was excluded or the rating discarded (empty: kept)"),
)

REQUIRED_COLUMNS = ("participant", "system", "stimulus", "value", "scale_min", "scale_max")
LABEL_COLUMNS = ("participant", "system", "stimulus", "task", "control_class")
APP_FLAG_COLUMNS = {"excluded_participant": "app_excluded_participant",
                    "discarded_early": "app_discarded_early"}
DEFAULT_LABEL = "all"
# Integer columns (ratings and scale ends) beyond this are a mistake in the file, not a
# rating scale; refusing them names the cell instead of overflowing int64 silently.
MAX_SCALE_MAGNITUDE = 1_000_000

_TRUE = {"true", "1", "yes", "y", "t"}
_FALSE = {"false", "0", "no", "n", "f", ""}


def read_ratings(source: str | os.PathLike | IO[str]) -> pd.DataFrame:
    """Read a ratings CSV (UTF-8) and return it validated and normalised (see `validate_ratings`)."""
    if isinstance(source, (str, os.PathLike)) and os.path.isdir(source):
        raise AnalysisInputError(f"{source!s} is a folder; give the ratings CSV file itself")
    text = _text(source)
    if is_genea_header(next(csv.reader(io.StringIO(text, newline="")), [])):
        return validate_ratings(genea_ratings(text, str(getattr(source, "name", source))))
    try:
        raw = pd.read_csv(io.StringIO(text), dtype=str, keep_default_na=False)
    except pd.errors.ParserError as exc:
        raise AnalysisInputError(f"ratings table {source!s} is not a regular CSV table: {exc}".strip()) from None
    except pd.errors.EmptyDataError:
        raise AnalysisInputError(f"ratings table {source!s} is empty: not even a header row") from None
    return validate_ratings(raw, source=source)


def _text(source: str | os.PathLike | IO[str]) -> str:
    try:
        if isinstance(source, (str, os.PathLike)):
            # utf-8-sig: a byte-order mark (as spreadsheets write) is not part of the first column's name
            with open(source, encoding="utf-8-sig", newline="") as file:
                return file.read()
        return source.read()
    except UnicodeDecodeError as exc:
        raise AnalysisInputError(
            f"ratings table {source!s} is not UTF-8 text (byte {exc.start} is "
            f"{exc.object[exc.start:exc.start + 1]!r}); save it as UTF-8 CSV") from None
    except OSError as exc:
        raise AnalysisInputError(f"cannot read ratings table {source!s}: {exc}") from exc


def validate_ratings(ratings: pd.DataFrame, source: str | os.PathLike | IO[str] | None = None) -> pd.DataFrame:
    """Check a ratings table against the schema and return a normalised copy.

    The copy has string labels (task and control_class filled with ``"all"`` when
    absent), integer value and scale columns, a boolean ``answered_before_end`` column
    when the timings allow it, and the app's own flags renamed with an ``app_`` prefix.
    Raises AnalysisInputError naming the offending column and rows otherwise (and the
    table's ``source`` where a message says the table is of another design).
    """
    design = design_of(ratings)
    required = design.required_columns(REQUIRED_COLUMNS)
    missing = [c for c in required if c not in ratings.columns]
    if missing:
        raise AnalysisInputError(_missing_columns_reason(ratings, design, missing, required, source))
    if len(ratings) == 0:
        raise AnalysisInputError("ratings table has no rows")
    if "design" not in ratings.columns:
        _refuse_shared_pages(ratings, source)
    df = ratings.rename(columns=APP_FLAG_COLUMNS).copy()
    for column in LABEL_COLUMNS:
        if column not in df.columns:
            df[column] = DEFAULT_LABEL
        df[column] = df[column].astype(str).str.strip()
        empty = df[column].isin(["", "nan", "None"])
        if empty.any():
            raise AnalysisInputError(
                f"column {column!r} is empty in {int(empty.sum())} row(s), first at row "
                f"{_row_number(df, empty)}"
            )
    if design.rated:
        _check_scale(df)
    for column in design.boolean_columns:
        df[column] = _booleans(df[column], column)
    df = design.check_pages(df)
    _refuse_duplicates(df)
    early = _answered_before_end(df)
    if early is not None:
        df["answered_before_end"] = early
    for column in APP_FLAG_COLUMNS.values():
        if column in df.columns:
            df[column] = _booleans(df[column], column)
    return df.reset_index(drop=True)


def _missing_columns_reason(ratings: pd.DataFrame, design: RatingDesign, missing: list[str],
                            required: tuple[str, ...], source: str | os.PathLike | IO[str] | None) -> str:
    """What a table lacking ``missing`` lacks: where it has no ``design`` column but every
    column of another design, the design column (it was read as single ratings); where it
    has some of a GENEA vote file's columns, the others."""
    if "design" not in ratings.columns:
        others = [design_named(name) for name in DESIGNS if name != DEFAULT]
        fitting = [other for other in others if set(other.required_columns(REQUIRED_COLUMNS)) <= set(ratings.columns)]
        if fitting:
            likely = max(fitting, key=lambda named: len(named.required_columns(REQUIRED_COLUMNS)))  # the most specific
            own = [c for c in likely.required_columns(REQUIRED_COLUMNS) if c not in REQUIRED_COLUMNS]
            return (f"{_table_name(source)} has no 'design' column, so it was read as single ratings, which need "
                    f"{', '.join(missing)}; its columns {', '.join(own)} are those of the {likely.name} design: add a "
                    f"column 'design' holding {likely.name!r} on every row (see docs/ratings-schema.md)")
        partial = [c for c in VOTE_COLUMNS if c not in ratings.columns]
        if len(partial) < len(VOTE_COLUMNS) - 1:
            return (f"ratings table lacks the required column(s) {', '.join(missing)}; as a GENEA vote file it lacks "
                    f"{', '.join(partial)} ({', '.join(VOTE_COLUMNS)} are its columns)")
    return (f"ratings table lacks the required column(s) {', '.join(missing)}; {design.schema_title()} is "
            f"{', '.join(required)} (see docs/ratings-schema.md)")


def _refuse_shared_pages(ratings: pd.DataFrame, source: str | os.PathLike | IO[str] | None) -> None:
    """A table without a ``design`` column is single ratings, one clip per page; a ``page``
    that several rows share is a screen of several clips, and analysing those ratings as
    independent single ones would be silently wrong. A ``page`` column with one row per
    page is carried through as any other column."""
    if "page" not in ratings.columns:
        return
    keys = pd.MultiIndex.from_arrays([ratings[c].astype(str).str.strip() for c in PAGE if c in ratings.columns])
    shared = pd.Series(keys.duplicated(keep=False), index=ratings.index)
    if shared.any():
        row = _row_number(ratings, shared)
        rows = int((keys == keys[row - 1]).sum())
        raise AnalysisInputError(
            f"{_table_name(source)} has no 'design' column, so it would be read as single ratings, one clip per page; "
            f"but its page {ratings['page'].iloc[row - 1]!r} of participant {ratings['participant'].iloc[row - 1]!r} "
            f"has {rows} rows (first at row {row}), so it looks like a side-by-side table: add a column 'design' "
            "holding 'side-by-side' on every row, or 'single' if they are single ratings all the same "
            "(see docs/ratings-schema.md)")


def _table_name(source: str | os.PathLike | IO[str] | None) -> str:
    """How a message names the table: by its file where it was read from one."""
    name = getattr(source, "name", source)  # an open file's path
    return f"ratings table {name!s}" if isinstance(name, (str, os.PathLike)) else "ratings table"


def _check_scale(df: pd.DataFrame) -> None:
    """Integer values on one declared scale per task (in place)."""
    for column in ("value", "scale_min", "scale_max"):
        df[column] = _integers(df[column], column)
    bad_scale = df["scale_min"] >= df["scale_max"]
    if bad_scale.any():
        raise AnalysisInputError(
            f"scale_min must be below scale_max; not so in {int(bad_scale.sum())} row(s), "
            f"first at row {_row_number(df, bad_scale)}"
        )
    outside = (df["value"] < df["scale_min"]) | (df["value"] > df["scale_max"])
    if outside.any():
        first = df.index[outside.to_numpy()][0]
        raise AnalysisInputError(
            f"{int(outside.sum())} rating(s) lie outside their declared scale, first at row "
            f"{_row_number(df, outside)}: value {df.at[first, 'value']} on "
            f"{df.at[first, 'scale_min']}..{df.at[first, 'scale_max']}"
        )
    scales = df.groupby("task")[["scale_min", "scale_max"]].nunique()
    mixed = scales[(scales > 1).any(axis=1)].index.tolist()
    if mixed:
        raise AnalysisInputError(
            f"task(s) {', '.join(map(str, mixed))} mix rating scales; ratings on different "
            "scales cannot enter one ANOVA (give each scale its own task)"
        )


def _answered_before_end(df: pd.DataFrame) -> pd.Series | None:
    if "answered_before_end" in df.columns:
        return _booleans(df["answered_before_end"], "answered_before_end")
    if {"played_until_s", "clip_duration_s"} <= set(df.columns):
        played = _floats(df["played_until_s"], "played_until_s")
        return played < _floats(df["clip_duration_s"], "clip_duration_s")
    if {"shown_at", "answered_at", "clip_duration_s"} <= set(df.columns):
        elapsed = _seconds(df["answered_at"], "answered_at") - _seconds(df["shown_at"], "shown_at")
        return elapsed < _floats(df["clip_duration_s"], "clip_duration_s")
    return None


def _refuse_duplicates(df: pd.DataFrame) -> None:
    """A row repeated whole (every column, timings included) is a copy, not a second
    rating, and would count twice; a repeated rating differs at least in its timings."""
    repeated = df.duplicated(keep="first")
    if repeated.any():
        copy = int(np.flatnonzero(repeated.to_numpy())[0])
        original = int(np.flatnonzero((df == df.iloc[copy]).all(axis=1).to_numpy())[0])
        raise AnalysisInputError(
            f"row {copy + 1} repeats row {original + 1} exactly (participant {df.iloc[copy]['participant']!r}, "
            f"stimulus {df.iloc[copy]['stimulus']!r}); {int(repeated.sum())} row(s) are such copies. "
            "Remove them: each rating must appear once")


def _row_number(df: pd.DataFrame, mask: pd.Series) -> int:
    # 1-based data row as a spreadsheet user counts it (header excluded)
    return int(np.flatnonzero(mask.to_numpy())[0]) + 1


def _integers(column: pd.Series, name: str) -> pd.Series:
    numbers = pd.to_numeric(column, errors="coerce").astype(np.float64)
    bad = ~np.isfinite(numbers) | (numbers != np.round(numbers)) | (numbers.abs() > MAX_SCALE_MAGNITUDE)
    if bad.any():
        first = column[bad].iloc[0]
        raise AnalysisInputError(
            f"column {name!r} must hold integers between {-MAX_SCALE_MAGNITUDE:,} and {MAX_SCALE_MAGNITUDE:,}; "
            f"{int(bad.sum())} row(s) do not, first at row {_row_number(column.to_frame(), bad)}: {first!r}"
        )
    return numbers.astype(np.int64)


def _floats(column: pd.Series, name: str) -> pd.Series:
    numbers = pd.to_numeric(column, errors="coerce").astype(np.float64)
    bad = ~np.isfinite(numbers)
    if bad.any():
        raise AnalysisInputError(
            f"column {name!r} must hold finite numbers (seconds); row "
            f"{_row_number(column.to_frame(), bad)} holds {column[bad].iloc[0]!r}"
        )
    return numbers.astype(np.float64)


def _seconds(column: pd.Series, name: str) -> pd.Series:
    """Seconds since an arbitrary origin from numbers or ISO 8601 timestamps."""
    numbers = pd.to_numeric(column, errors="coerce")
    if not numbers.isna().any():
        return _floats(column, name)
    try:
        times = pd.to_datetime(column, utc=True, format="ISO8601")
    except (ValueError, TypeError) as exc:
        raise AnalysisInputError(
            f"column {name!r} must hold ISO 8601 timestamps or seconds: {exc}"
        ) from exc
    if times.isna().any():
        raise AnalysisInputError(f"column {name!r} has empty timestamps")
    return (times - pd.Timestamp(0, tz="UTC")).dt.total_seconds()


def _booleans(column: pd.Series, name: str) -> pd.Series:
    if column.dtype == bool:
        return column
    text = column.astype(str).str.strip().str.lower()
    unknown = ~text.isin(_TRUE | _FALSE)
    if unknown.any():
        raise AnalysisInputError(
            f"column {name!r} must hold true/false; row "
            f"{_row_number(column.to_frame(), unknown)} holds {column[unknown].iloc[0]!r}"
        )
    return text.isin(_TRUE)
