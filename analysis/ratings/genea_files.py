"""The GENEA leaderboard's vote files, read as they are and written back unchanged.

GENEA's battles file has one row per vote: ``user, input_code, model_a, model_b, winner,
is_strong`` and the reasons ``juiceOptions, juiceOtherReason`` (any further columns are
kept too). ``winner`` is ``model_a`` (the left clip), ``model_b`` (the right one), ``tie``
or ``tie (bothbad)``; ``is_strong`` is ``True`` (clearly better), ``False`` (slightly) or
empty (a plain answer). Its mismatch (appropriateness) file has the same columns, each
page showing one system's clip for the shown speech and, named ``<system>_Mismatched``,
its clip for another.

`genea_ratings` turns such a file into the project's table (docs/ratings-schema.md): two
rows per page with ``design`` ``pairwise`` or ``appropriateness``, ``side`` (model_a
left), ``answer`` and ``strength`` (clearly 2, slightly 1, empty for a plain answer and for
a tie, whose strength GENEA's own fit ignores), ``matched`` for the mismatch file, the
vote's line as its ``page`` and ``input_code`` as the clip's control, and the reasons in
their own columns (``juiceOptions``, ``juiceOtherReason``: `analysis.reports.reasons` counts them). Every original
column rides along on both rows as ``genea:<column>``, text untouched, so `genea_csv`
writes the file back byte for byte: same columns, order, values and line endings, quoted
where a field needs it (as pandas and Python's csv module write, GENEA's exports included).
A table the study app exported gets its GENEA columns from the project's own, its reasons
(where its pages asked for them) in GENEA's two reason columns.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass

import pandas as pd

from analysis.pages import NO_PREFERENCE
from analysis.errors import AnalysisInputError

VOTE_COLUMNS = ("user", "input_code", "model_a", "model_b", "winner", "is_strong")
REASON_COLUMNS = ("juiceOptions", "juiceOtherReason")
CARRIED = "genea:"  # prefix of the original columns in the project's table
MISMATCHED = "_Mismatched"  # GENEA's suffix of a system's clip made for another input
ANSWER_OF_WINNER = {"model_a": "left", "model_b": "right", "tie": NO_PREFERENCE, "tie (bothbad)": NO_PREFERENCE}
WINNER_OF_ANSWER = {"left": "model_a", "right": "model_b", NO_PREFERENCE: "tie"}
STRENGTH_OF_STRONG = {"True": "2", "False": "1", "": ""}
STRONG_OF_STRENGTH = {2: "True", 1: "False"}


@dataclass(frozen=True)
class GeneaLayout:
    """How a GENEA file was written: its columns in order and its line ending."""

    columns: tuple[str, ...] = (*VOTE_COLUMNS, *REASON_COLUMNS)
    line_ending: str = "\n"
    ends_with_line_ending: bool = True


def is_genea_header(columns: Sequence[str]) -> bool:
    """Whether a header is GENEA's vote file rather than the project's ratings table."""
    return set(VOTE_COLUMNS) <= set(columns) and not {"design", "participant"} & set(columns)


def genea_layout(text: str) -> GeneaLayout:
    """The columns and line ending of a GENEA file's text."""
    header = next(csv.reader(io.StringIO(text, newline="")), [])
    first_break = text.find("\n")
    line_ending = "\r\n" if first_break > 0 and text[first_break - 1] == "\r" else "\n"
    return GeneaLayout(tuple(header), line_ending, text.endswith(line_ending))


def _records(text: str) -> list[tuple[int, dict[str, str]]]:
    """(first line, fields) per vote; a record quoting a line break spans more lines."""
    reader = csv.reader(io.StringIO(text, newline=""))
    header = next(reader)
    records, line = [], reader.line_num + 1
    for fields in reader:
        if fields:
            if len(fields) != len(header):
                raise AnalysisInputError(f"line {line}: {len(fields)} fields where the header names {len(header)}")
            records.append((line, dict(zip(header, fields))))
        line = reader.line_num + 1
    return records


def genea_ratings(text: str, source: str = "the GENEA file") -> pd.DataFrame:
    """The project's pairwise or appropriateness table of a GENEA vote file's text.

    Raises AnalysisInputError naming the file, line and column of the first bad vote.
    """
    try:
        records = _records(text)
    except (AnalysisInputError, csv.Error) as error:
        raise AnalysisInputError(f"{source}, {error}") from None
    if not records:
        raise AnalysisInputError(f"{source} has no votes below its header")
    mismatch = any(f[m].endswith(MISMATCHED) for _, f in records for m in ("model_a", "model_b"))
    rows = []
    for line, fields in records:
        def refuse(column: str, why: str) -> AnalysisInputError:
            return AnalysisInputError(f"{source}, line {line}, column {column!r}: {fields[column]!r} {why}")

        for column in ("user", "input_code", "model_a", "model_b"):
            if not fields[column].strip():
                raise refuse(column, "is empty")
        if fields["winner"] not in ANSWER_OF_WINNER:
            raise refuse("winner", f"is none of {', '.join(ANSWER_OF_WINNER)}")
        if fields["is_strong"] not in STRENGTH_OF_STRONG:
            raise refuse("is_strong", "is not True, False or empty")
        answer = ANSWER_OF_WINNER[fields["winner"]]
        strength = STRENGTH_OF_STRONG[fields["is_strong"]] if answer != NO_PREFERENCE else ""
        systems = {side: fields[model] for side, model in (("left", "model_a"), ("right", "model_b"))}
        matched = {side: not name.endswith(MISMATCHED) for side, name in systems.items()}
        if mismatch:
            bases = {name.removesuffix(MISMATCHED) for name in systems.values()}
            if sum(matched.values()) != 1 or len(bases) != 1:
                raise refuse("model_b", f"with model_a {fields['model_a']!r} is no mismatch page: one system's "
                                        f"clip and its {MISMATCHED} clip, as every other page of this file")
        carried = {CARRIED + column: value for column, value in fields.items()}
        reasons = {column: fields[column] for column in REASON_COLUMNS if column in fields}  # analysis.reports.reasons
        for side, name in systems.items():
            rows.append({"participant": fields["user"], "page": str(line),
                         "system": name.removesuffix(MISMATCHED) if mismatch else name,
                         "stimulus": f"{name}/{fields['input_code']}", "control": fields["input_code"],
                         "side": side, "answer": answer, "strength": strength,
                         **({"matched": str(matched[side]).lower()} if mismatch else {}), **reasons, **carried})
    table = pd.DataFrame(rows)
    table.insert(0, "design", "appropriateness" if mismatch else "pairwise")
    return table


def genea_csv(table: pd.DataFrame, layout: GeneaLayout | None = None) -> str:
    """A pairwise or appropriateness table (as `analysis.ratings.schema.read_ratings` returns it)
    as GENEA's vote file, one line per page in the table's order. A table read from a GENEA
    file is written back as it was; ``layout`` (`genea_layout` of that file) keeps its
    columns and line ending. Raises AnalysisInputError for a strength above 2: GENEA's
    votes are clearly or slightly better."""
    reasons = [c for c in REASON_COLUMNS if c in table.columns]  # the study app's, in GENEA's columns
    layout = layout or GeneaLayout(tuple(dict.fromkeys(
        [*VOTE_COLUMNS, *reasons, *(c.removeprefix(CARRIED) for c in table.columns if c.startswith(CARRIED))])))
    left = table[table["side"] == "left"].reset_index(drop=True)
    right = table[table["side"] == "right"].set_index(["task", "participant", "page"]).loc[
        pd.MultiIndex.from_frame(left[["task", "participant", "page"]])].reset_index()
    strength = pd.to_numeric(left["strength"], errors="coerce") if "strength" in left else pd.Series(pd.NA, left.index)
    beyond = strength.notna() & ~strength.isin(list(STRONG_OF_STRENGTH))
    if beyond.any():
        raise AnalysisInputError(f"GENEA's votes are clearly or slightly better (strength 2 or 1); page "
                                 f"{left.loc[beyond, 'page'].iloc[0]!r} has strength {strength[beyond].iloc[0]:g}")

    def model(side: pd.DataFrame) -> pd.Series:
        if "matched" not in side:
            return side["system"]
        return side["system"] + side["matched"].map({True: "", False: MISMATCHED})

    derived = pd.DataFrame({
        "user": left["participant"], "input_code": left.get("control", left["stimulus"]),
        "model_a": model(left), "model_b": model(right),
        "winner": left["answer"].map(WINNER_OF_ANSWER),
        "is_strong": strength.map(STRONG_OF_STRENGTH).where(left["answer"] != NO_PREFERENCE).fillna(""),
        **{c: left[c].fillna("") for c in reasons}})
    fields = pd.DataFrame({c: left[CARRIED + c] if CARRIED + c in left else derived[c] for c in layout.columns})
    out = io.StringIO(newline="")
    writer = csv.writer(out, lineterminator=layout.line_ending)
    writer.writerow(layout.columns)
    writer.writerows(fields.itertuples(index=False, name=None))
    text = out.getvalue()
    return text if layout.ends_with_line_ending else text.removesuffix(layout.line_ending)
