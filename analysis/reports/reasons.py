"""Why participants answered as they did: each system's reason counts, as GENEA plots them.

A pairwise or side-by-side page may carry the reasons its participant gave, in GENEA's
battles-file columns, the same on every row of the page: ``juiceOptions``, the options
ticked as GENEA writes them (a Python dict of lists of options, ``{}`` for none; the
study app writes its list under ``reasons``: ``{'reasons': ['Motion smoothness']}``),
and ``juiceOtherReason``, the participant's own words under "Other" (counted as the
reason ``Other``).

A page's reasons count for the system its answer chose: a pairwise page's preferred
clip, a side-by-side page's clip rated highest. A tie (no preference; several clips
sharing a side-by-side page's top rating) chose none: its reasons are counted for each
tied system in a column of their own (``ties``), never in ``count``. Per cell and system,
``pages`` is how many pages chose it and ``share`` the part of them giving the reason.
"""

from __future__ import annotations

import ast
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from analysis.pages import NO_PREFERENCE
from analysis.reports import plots
from analysis.reports.tables import write_table
from analysis.stats.anova import CELL

OPTIONS, OTHER_WORDS = "juiceOptions", "juiceOtherReason"
REASON_COLUMNS = (OPTIONS, OTHER_WORDS)
APP_KEY = "reasons"  # the key of the study app's options in juiceOptions
OTHER = "Other"
MAX_OPTIONS_CHARS = 10_000  # a cell longer than this is no list of reasons
PAGE = ["task", "participant", "page"]
COUNT_COLUMNS = [*CELL, "system", "reason", "count", "pages", "share", "ties"]
CAPTION = ("Reasons given per system: count, the pages that chose the system giving the reason (of pages, "
           "those choosing it), and ties, the pages without a choice (no preference, or a shared top rating) "
           "on which the system was tied, giving the reason")


def options_text(options: Sequence[str]) -> str:
    """Ticked options as GENEA's ``juiceOptions`` holds them: ``{}`` for none."""
    return repr({APP_KEY: list(options)}) if options else "{}"


def read_options(text: str) -> list[str]:
    """The options of a ``juiceOptions`` cell, in order, each once: every text in the
    lists of its dict (or in a plain list); ValueError for a cell that is neither."""
    text = (text or "").strip()
    if not text:
        return []
    if len(text) > MAX_OPTIONS_CHARS:
        raise ValueError(f"{len(text):,} characters, more than a list of reasons holds")
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        raise ValueError(f"{text[:60]!r} is not a dict or list of options") from None
    groups = value.values() if isinstance(value, dict) else [value]
    options = []
    for group in groups:
        for option in group if isinstance(group, list | tuple) else [group]:
            if not isinstance(option, str):
                raise ValueError(f"{text[:60]!r} holds {option!r}, not the text of an option")
            options.append(option.strip())
    return list(dict.fromkeys(o for o in options if o))


def has_reasons(table: pd.DataFrame) -> bool:
    """Whether a ratings table carries reasons (GENEA's columns, any of them filled)."""
    return any((~table[c].fillna("").astype(str).str.strip().isin(["", "{}"])).any()
               for c in REASON_COLUMNS if c in table.columns)


def _page_choices(kept: pd.DataFrame) -> pd.DataFrame:
    """One row per page: its cell, the system it chose ("" for a tie), the systems a tie
    leaves tied (empty where it chose one), and its reasons' cells."""
    by_page = kept.groupby(PAGE, sort=True)
    first = by_page.first()
    if "side" in kept.columns and "answer" in kept.columns:  # pairwise: the preferred side's system
        side = kept.set_index([*PAGE, "side"])["system"]
        chosen = [side.get((*key, answer), "") if answer != NO_PREFERENCE else ""
                  for key, answer in zip(first.index, first["answer"])]
        both = by_page["system"].agg(lambda s: sorted(set(s))).reindex(first.index)
        tied = [[] if c else systems for c, systems in zip(chosen, both)]
    else:  # side-by-side: the clip rated highest, unless several share the top
        top = kept[kept["value"] == by_page["value"].transform("max")]
        tops = top.groupby(PAGE)["system"].agg(lambda s: sorted(set(s))).reindex(first.index)
        chosen = [systems[0] if len(systems) == 1 else "" for systems in tops]
        tied = [[] if len(systems) == 1 else systems for systems in tops]
    blank = pd.Series("", first.index)
    return pd.DataFrame({"control_class": first["control_class"], "chosen": chosen, "tied": tied,
                         "options": first.get(OPTIONS, blank).fillna(""),
                         "other": first.get(OTHER_WORDS, blank).fillna("")}, index=first.index).reset_index()


def reason_counts(kept: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Per cell, system and reason given: ``COUNT_COLUMNS`` (see the module's docstring),
    every system of the cell with every reason given there (zeros included); notes name
    the pages whose ``juiceOptions`` could not be read (their options not counted)."""
    pages = _page_choices(kept)
    notes, given = [], []
    for row in pages.itertuples(index=False):
        try:
            options = read_options(str(row.options))
        except ValueError as error:
            notes.append(f"Reasons of participant {row.participant}'s page {row.page}: juiceOptions {error}; "
                         "its options are not counted.")
            options = []
        other = str(row.other).strip()
        given.append(options + ([OTHER] if other and OTHER not in options else []))
    pages["reasons"] = given
    rows = []
    for key, cell in pages.groupby(list(CELL), sort=True):
        reasons = list(dict.fromkeys(r for listed in cell["reasons"] for r in listed))
        systems = sorted(set(kept.loc[(kept["task"] == key[0]) & (kept["control_class"] == key[1]), "system"]))
        for system in systems:
            won = cell[cell["chosen"] == system]
            tied = cell[cell["tied"].map(lambda s, name=system: name in s)]
            for reason in reasons:
                count = int(won["reasons"].map(lambda r, name=reason: name in r).sum())
                rows.append({"task": key[0], "control_class": key[1], "system": system, "reason": reason,
                             "count": count, "pages": len(won), "share": count / len(won) if len(won) else np.nan,
                             "ties": int(tied["reasons"].map(lambda r, name=reason: name in r).sum())})
    if len(notes) > 5:
        notes = notes[:5] + [f"... and {len(notes) - 5} more pages whose juiceOptions could not be read."]
    return pd.DataFrame(rows, columns=COUNT_COLUMNS), notes


def reasons_plot(counts: pd.DataFrame) -> Figure:
    """A grouped bar chart per cell: for each system, a bar per reason (the pages that chose it giving it)."""
    cells = counts[list(CELL)].drop_duplicates().to_numpy().tolist()
    figure = Figure(figsize=(8, 3.2 * len(cells)), layout="constrained")
    axes = figure.subplots(len(cells), 1, squeeze=False)[:, 0]
    for ax, (task, cc) in zip(axes, cells):
        cell = counts[(counts["task"] == task) & (counts["control_class"] == cc)]
        systems, reasons = list(dict.fromkeys(cell["system"])), list(dict.fromkeys(cell["reason"]))
        width = 0.8 / max(len(reasons), 1)
        table = cell.pivot(index="system", columns="reason", values="count").reindex(index=systems, columns=reasons)
        for k, reason in enumerate(reasons):
            ax.bar(np.arange(len(systems)) + (k - (len(reasons) - 1) / 2) * width, table[reason].to_numpy(),
                   width, label=plots.plain_text(reason))
        ax.set_xticks(np.arange(len(systems)), [plots.plain_text(system) for system in systems])
        ax.set_ylabel("pages choosing the system")
        ax.set_title(plots.plain_text(f"Reasons per system, {task} · {cc}"))
        ax.legend(fontsize="small", ncols=min(len(reasons), 3))
    return figure


def write_reasons(counts: pd.DataFrame, folder: Path) -> list[Path]:
    """The counts as tables/reasons.{csv,md,tex,json} and their chart as figures/reasons.{png,svg}."""
    if counts.empty:
        return []
    return [*write_table(counts, folder / "tables", "reasons", caption=f"{CAPTION}."),
            *plots.save_figure(reasons_plot(counts), folder / "figures", "reasons")]
