"""The analysis's tidy tables as the report page and the monitor show them: headers in
words, numbers rounded for reading, "–" where a value does not exist (never NaN), and
the columns that hold one value for every row (the task, the control class, the unit the
power table counts in) said once above the table instead of in every row, so a table
fits the page. The files of the report keep the tidy tables as they are.
"""

from __future__ import annotations

import math
from numbers import Number

import pandas as pd
from django.utils.html import escape
from django.utils.safestring import SafeString, mark_safe

# Column names of the analysis's tables in words; any other is its name with spaces.
HEADERS = {
    "system": "System", "system_a": "System A", "system_b": "System B", "task": "Task", "control_class": "Control",
    "n": "n", "mean": "Mean", "sd": "SD", "sem": "SEM", "ci_half": "± (95 % CI)", "ci_low": "CI low",
    "ci_high": "CI high", "median": "Median", "median_ci_low": "Median CI low", "median_ci_high": "Median CI high",
    "effect": "Effect", "alpha_pair": "α per pair", "unit": "Counted in", "n_now": "So far",
    "power_now": "Power so far", "n_needed": "Needed for 80 % power", "n_more": "More needed",
    "per_participant": "Per participant", "participants_more": "More participants", "p": "p",
    "p_adj": "p (adjusted)", "p_holm": "p (Holm)", "reject": "Significant", "eta_squared": "η²",
    "df_between": "df between", "df_within": "df within", "n_systems": "Systems", "n_ratings": "Ratings",
    "n_pages": "Pages", "n_participants": "Participants", "meandiff": "Mean difference",
    "group1": "System A", "group2": "System B", "lower": "CI low", "upper": "CI high",
}
# Columns that say where a row belongs rather than what was found: said once where every row shares them.
CONTEXT = ("task", "control_class", "unit", "alpha_pair")


def header(name: object) -> str:
    text = str(name)
    return HEADERS.get(text, text.replace("_", " "))


def cell_text(value: object) -> str:
    """A value as read: "–" for a missing one, whole numbers without decimals, others to
    four significant digits, yes and no for a truth value."""
    if value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, Number) and not isinstance(value, complex):
        number = float(value)
        if math.isinf(number):
            return "∞" if number > 0 else "−∞"
        if number.is_integer() and abs(number) < 1e15:
            return f"{int(number):,}"
        return f"{number:.4g}"
    return str(value)


def _context(table: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """The table without the context columns every row shares, and those columns in words."""
    shared = [name for name in CONTEXT if name in table.columns and len(table) and table[name].nunique(dropna=False) == 1]
    said = [f"{header(name)}: {cell_text(table[name].iloc[0])}" for name in shared]
    return table.drop(columns=shared), said


def readable_table(table: pd.DataFrame) -> SafeString:
    """``table`` as escaped HTML for reading (MultiIndex columns flattened), its shared
    context said in a caption."""
    flat = table.copy()
    if isinstance(flat.columns, pd.MultiIndex):
        flat.columns = [" · ".join(str(p) for p in c if str(p)) for c in flat.columns]
    flat, said = _context(flat)
    show_index = not isinstance(flat.index, pd.RangeIndex)
    shown = flat.map(cell_text).rename(columns=header)
    if show_index:
        shown.index = shown.index.map(cell_text)
    html = shown.to_html(index=show_index, escape=True, border=0, classes="data")
    if said:
        caption = f'<caption class="meta">{escape(" · ".join(said))}</caption>'
        html = html.replace(">\n", ">\n" + caption + "\n", 1)
    return mark_safe(html)  # pandas escaped every cell and header, the caption is escaped above


__all__ = ["cell_text", "header", "readable_table"]
