"""The papers' table layouts, and writing any table as CSV, Markdown, LaTeX and JSON.

- `significance_table`: MoGlow Table 2. Systems as rows, task x control class as
  columns, cells ``mean±ci`` (95 % CI half-width) with ``**`` / ``*`` where Tukey HSD
  finds the system different from the reference at p < 0.01 / p < 0.05, ``-`` where the
  system was not evaluated.
- `objective_table`: MoGlow Table 3. Systems as rows, metrics as columns, the value
  closest to the natural system's marked in each column (bold in Markdown and LaTeX).

Display tables hold strings, so what a reader sees in every format is the same text;
there are no NaN cells, a missing value is always a dash or words. Labels come from
whoever wrote the ratings, so every format escapes them: LaTeX and Markdown specials,
HTML in Markdown, and spreadsheet formulas in CSV (`spreadsheet_safe`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.motion.objective import METRIC_COLUMNS

NOT_EVALUATED = "-"
CLOSEST_MARK = "†"  # plain-text mark; Markdown and LaTeX render the cell bold instead
FEW_PARTICIPANTS_MARK = " ‡"  # after a Table 2 cell whose interval rests on few participants (analysis.stats.minimums)


def significance_stars(p: float) -> str:
    return "**" if p < 0.01 else "*" if p < 0.05 else ""


def system_order(systems: Sequence[str], reference: str | None) -> list[str]:
    """The reference first (as MoGlow lists NAT first), then the rest alphabetically."""
    rest = sorted(s for s in set(systems) if s != reference)
    return ([reference] if reference in set(systems) else []) + rest


def significance_table(means: pd.DataFrame, pairs: pd.DataFrame, reference: str | None,
                       too_few: pd.DataFrame | None = None, decimals: int = 2) -> pd.DataFrame:
    """MoGlow Table 2 from `system_means` and `tukey_hsd` output.

    ``too_few`` (columns task, control_class, system, n) lists systems left out of a
    cell for having fewer than two ratings; their cell says so instead of a dash. A mean
    whose ``warning`` column (`analysis.stats.minimums.with_participant_warnings`) says its
    interval rests on few participants is marked ``FEW_PARTICIPANTS_MARK``.
    """
    columns = pd.MultiIndex.from_frame(
        means[["task", "control_class"]].drop_duplicates().sort_values(["task", "control_class"]))
    rows = system_order(means["system"], reference)
    if too_few is not None:
        rows += [s for s in system_order(too_few["system"], None) if s not in rows]
    table = pd.DataFrame(NOT_EVALUATED, index=pd.Index(rows, name="system"), columns=columns)
    against = {}
    if reference is not None and len(pairs):
        mine = pairs[(pairs["system_a"] == reference) | (pairs["system_b"] == reference)]
        for row in mine.itertuples(index=False):
            other = row.system_b if row.system_a == reference else row.system_a
            against[(row.task, row.control_class, other)] = row.p_adj
    for row in means.itertuples(index=False):
        stars = significance_stars(against.get((row.task, row.control_class, row.system), 1.0))
        few = FEW_PARTICIPANTS_MARK if getattr(row, "warning", "") else ""
        table.loc[row.system, (row.task, row.control_class)] = (
            f"{row.mean:.{decimals}f}±{row.ci_half:.{decimals}f}{stars}{few}")
    if too_few is not None:
        for row in too_few.itertuples(index=False):
            if (row.task, row.control_class) in table.columns:
                table.loc[row.system, (row.task, row.control_class)] = f"n={row.n}, not computed"
    return table


def objective_table(metrics: pd.DataFrame, natural: str = "NAT", decimals: int = 2) -> pd.DataFrame:
    """MoGlow Table 3 from `objective_metrics` output, closest-to-natural values marked."""
    table = metrics.set_index("system")[list(METRIC_COLUMNS)]
    text = table.map(lambda v: f"{v:.{decimals}f}" if np.isfinite(v) else "not computed")
    if natural in table.index:
        for column in table.columns:
            others = table[column].drop(natural)
            distance = (others - table.at[natural, column]).abs().dropna()
            if len(distance):
                closest = distance.min()
                for system in distance.index[np.isclose(distance, closest)]:
                    text.at[system, column] += CLOSEST_MARK
    order = system_order(table.index, natural)
    return text.loc[order].rename_axis("system")


def pvalue_display(matrix: pd.DataFrame) -> pd.DataFrame:
    """Adjusted p-values as text; the diagonal (a system against itself) as a dash."""
    text = matrix.map(lambda p: NOT_EVALUATED if pd.isna(p) else "<0.001" if p < 0.001 else f"{p:.3f}")
    return text


# ---- writers ---------------------------------------------------------------------------

# A text cell starting with one of these is run as a formula by spreadsheet programs
# (OWASP, "CSV Injection"); a leading apostrophe makes them show it as text.
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_safe(value):
    """``value`` with a leading ``'`` when it is text a spreadsheet would run as a formula.

    Numbers (``-1.5`` as text too) and the not-evaluated dash are left alone.
    """
    if not isinstance(value, str) or not value.startswith(_FORMULA_START) or value == NOT_EVALUATED:
        return value
    try:
        float(value)
    except ValueError:
        return "'" + value
    return value


def _header_text(column) -> str:
    return " · ".join(map(str, column)) if isinstance(column, tuple) else str(column)


def _flat(table: pd.DataFrame) -> pd.DataFrame:
    flat = table.copy()
    flat.columns = [_header_text(c) for c in table.columns]
    return flat.reset_index() if table.index.name else flat


def _text(value) -> str:
    """Numbers in tidy tables shown with four significant digits; CSV and JSON keep all."""
    if isinstance(value, (float, np.floating)):
        return "not computed" if not np.isfinite(value) else f"{value:.4g}"
    return str(value)


_MARKDOWN_SPECIAL = {"|": "\\|", "*": "\\*", "_": "\\_", "\\": "\\\\", "`": "\\`", "[": "\\[", "]": "\\]",
                     "<": "&lt;", ">": "&gt;", "&": "&amp;", "\n": " ", "\r": " "}


def _markdown_cell(value, marked: bool = True) -> str:
    """A cell's text with Markdown and HTML escaped and line breaks (which end a table row)
    made spaces; ``marked`` cells ending in the closest-value mark are bold."""
    text = _text(value)
    bold = marked and text.endswith(CLOSEST_MARK)
    text = "".join(_MARKDOWN_SPECIAL.get(ch, ch) for ch in (text[:-1] if bold else text))
    return f"**{text}**" if bold else text


def to_markdown(table: pd.DataFrame) -> str:
    flat = _flat(table)
    lines = ["| " + " | ".join(_markdown_cell(c, marked=False) for c in flat.columns) + " |",
             "|" + "|".join(["---"] + ["---:"] * (len(flat.columns) - 1)) + "|"]
    lines += ["| " + " | ".join(_markdown_cell(v) for v in row) + " |"
              for row in flat.itertuples(index=False)]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {"&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
                  "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                  "\\": r"\textbackslash{}", "<": r"\textless{}", ">": r"\textgreater{}"}


# A significance cell: "mean±ci" then its stars; only these carry stars as marks.
_SIGNIFICANCE_CELL = re.compile(r"^-?\d+(\.\d+)?±\d+(\.\d+)?(?P<stars>\*+)(?P<few>"
                                + re.escape(FEW_PARTICIPANTS_MARK) + ")?$")


def _latex_cell(value, marked: bool = True) -> str:
    """A cell in LaTeX; ``marked`` cells turn a closest-value mark into bold and a
    significance cell's stars into superscripts. Labels are never marked, so a system
    named ``GAN*`` does not look significant."""
    text = _text(value).replace("\n", " ").replace("\r", " ")
    bold = marked and text.endswith(CLOSEST_MARK)
    if bold:
        text = text[:-1]
    stars = _SIGNIFICANCE_CELL.match(text) if marked else None
    if stars:
        text = text[: stars.start("stars")]
    text = "".join(_LATEX_SPECIAL.get(ch, ch) for ch in text)
    text = text.replace("±", r"$\pm$")
    if stars:
        text += f"$^{{{stars.group('stars')}}}$" + (stars.group("few") or "")
    return rf"\textbf{{{text}}}" if bold else text


def to_latex(table: pd.DataFrame, caption: str = "") -> str:
    """A booktabs tabular; two-level columns get grouped headers with cmidrules."""
    index_name = table.index.name or ""
    n = len(table.columns)
    lines = [r"\begin{tabular}{l" + "r" * n + "}", r"\toprule"]
    if isinstance(table.columns, pd.MultiIndex) and table.columns.nlevels == 2:
        groups, rules, start = [""], [], 2
        for top, members in pd.Series(table.columns.get_level_values(0)).groupby(
                table.columns.get_level_values(0), sort=False):
            groups.append(rf"\multicolumn{{{len(members)}}}{{c}}{{{_latex_cell(top, marked=False)}}}")
            rules.append(rf"\cmidrule(lr){{{start}-{start + len(members) - 1}}}")
            start += len(members)
        lines += [" & ".join(groups) + r" \\", " ".join(rules)]
        names = [_latex_cell(n, marked=False) for n in [index_name, *table.columns.get_level_values(1)]]
    else:
        names = [_latex_cell(n, marked=False) for n in [index_name, *map(_header_text, table.columns)]]
    lines += [" & ".join(names) + r" \\", r"\midrule"]
    for label, row in table.iterrows():
        lines.append(" & ".join([_latex_cell(label, marked=False)] + [_latex_cell(v) for v in row]) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    if caption:
        lines.insert(0, f"% {caption}")
    return "\n".join(lines) + "\n"


def _spreadsheet_safe_table(table: pd.DataFrame) -> pd.DataFrame:
    safe = table.map(spreadsheet_safe)
    safe.columns = [spreadsheet_safe(c) for c in table.columns]
    return safe


def _json_ready(table: pd.DataFrame) -> list[dict]:
    records = _flat(table).to_dict(orient="records")
    # NaN is not JSON; in numeric tables it only marks a value that was not computed
    return [{k: (None if isinstance(v, float) and not np.isfinite(v) else
                 v.item() if isinstance(v, np.generic) else v) for k, v in r.items()}
            for r in records]


def write_table(table: pd.DataFrame, folder: str | Path, name: str, caption: str = "",
                formats: Sequence[str] = ("csv", "md", "tex", "json")) -> list[Path]:
    """Write one table as name.csv / .md / .tex / .json in folder; return the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    writers = {
        "csv": lambda: _spreadsheet_safe_table(_flat(table)).to_csv(index=False),
        "md": lambda: (f"{_markdown_cell(caption, marked=False)}\n\n" if caption else "") + to_markdown(table),
        "tex": lambda: to_latex(table, " ".join(caption.split())),  # one line: it is a comment
        "json": lambda: json.dumps(_json_ready(table), indent=1, ensure_ascii=False) + "\n",
    }
    paths = []
    for fmt in formats:
        path = folder / f"{name}.{fmt}"
        path.write_text(writers[fmt](), encoding="utf-8")
        paths.append(path)
    return paths


def slug(*parts) -> str:
    """A file-name-safe name from labels such as a task and a control class."""
    return "_".join(re.sub(r"[^A-Za-z0-9.-]+", "-", str(p)).strip("-") or "x" for p in parts)
