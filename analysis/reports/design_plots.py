"""Figures of the side-by-side and pairwise designs (the single design's are in `analysis.reports.plots`).

- `significance_matrix_plot`: GENEA's significance matrix, one panel per task x control
  class: a cell is green where the row system was rated significantly higher than the
  column system, red where lower, grey where the difference is not significant (Holm
  corrected), white on the diagonal and where no test ran.
- `scale_plot`: a value per system with its 95 % interval, one panel per cell: the
  median and mean of side-by-side ratings, or the Bradley-Terry strengths.
- `preference_plot`: per pair, the share of pages preferring each system, with the
  Wilson interval and the share answered "no preference".
- `appropriateness_plots`: per system, the share of appropriateness pages preferring the
  matched clip (on 0..1) and the mean appropriateness score (on -2..+2), each with its
  interval, every panel on the whole range.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from analysis.reports.plots import _cell_axes, fit_scale, interval_errors, plain_text, plt
from analysis.stats.within_page import significance_matrix

_MATRIX_COLOURS = ListedColormap(["#d7301f", "#bdbdbd", "#2ca25f"])  # lower, n.s., higher


def _cells(table: pd.DataFrame) -> list[tuple]:
    return sorted(table.groupby(["task", "control_class"]).groups)


def _in_cell(table: pd.DataFrame, cell: tuple) -> pd.DataFrame:
    return table[(table["task"] == cell[0]) & (table["control_class"] == cell[1])]


def significance_matrix_plot(pairs: pd.DataFrame, order_by: pd.DataFrame) -> Figure:
    """`signed_rank_pairs` output as matrices; systems ordered by ``order_by``'s median
    (then mean), highest first, per cell."""
    cells = _cells(pairs)
    size = max(order_by.groupby(["task", "control_class"]).size())
    side = 0.9 + 0.45 * size
    fig, axes = plt.subplots(1, len(cells), figsize=(side * len(cells) + 2.0, side + 0.6), squeeze=False)
    for ax, cell in zip(axes[0], cells):
        ranked = _in_cell(order_by, cell).sort_values(["median", "mean"], ascending=False)
        order = list(ranked["system"])
        matrix = significance_matrix(_in_cell(pairs, cell), order).to_numpy()
        ax.imshow(np.ma.masked_invalid(matrix), cmap=_MATRIX_COLOURS, vmin=-1, vmax=1)
        ax.set_xticks(range(len(order)), [plain_text(s) for s in order], rotation=90)
        ax.set_yticks(range(len(order)), [plain_text(s) for s in order])
        ax.set_title(plain_text(f"{cell[0]} · {cell[1]}"), fontsize="medium")
        ax.set_xlabel("compared with")
    axes[0][0].set_ylabel("row system")
    axes[0][-1].legend(handles=[Patch(color=_MATRIX_COLOURS(2), label="row rated higher"),
                                Patch(color=_MATRIX_COLOURS(1), label="not significant"),
                                Patch(color=_MATRIX_COLOURS(0), label="row rated lower")],
                       bbox_to_anchor=(1.02, 1), loc="upper left", fontsize="small")
    fig.tight_layout()
    return fig


def scale_plot(table: pd.DataFrame, estimates: Sequence[tuple[str, str, str, str]],
               xlabel: str, order: Sequence[str], scale: tuple[float, float] | None = None) -> Figure:
    """Point estimates with intervals per system; ``estimates`` lists (label, value column,
    low column, high column), drawn side by side for each system. With a ``scale`` (a
    rating scale, a share's 0..1) every panel's axis spans it and the intervals are cut at
    its ends. The axis label stands once under the panels (one per panel ran into the next);
    a system with nothing in a panel's cell is said to have none there, its row not left blank."""
    cells = _cells(table)
    position = {system: len(order) - 1 - i for i, system in enumerate(order)}
    fig, axes = _cell_axes(cells, order, legend_in=0.9 if len(estimates) > 1 else 0.0)
    offsets = np.linspace(-0.15, 0.15, len(estimates)) if len(estimates) > 1 else [0.0]
    for ax, cell in zip(axes, cells):
        frame = _in_cell(table, cell)
        y = frame["system"].map(position).to_numpy(dtype=float)
        for offset, (label, value, low, high) in zip(offsets, estimates):
            error = interval_errors(frame[value], frame[low], frame[high], scale)
            ax.errorbar(frame[value].to_numpy(dtype=float), y + offset, xerr=error, fmt="o", capsize=3, label=label)
        ax.set_title(plain_text(f"{cell[0]} · {cell[1]}"), fontsize="medium")
        fit_scale(ax, scale)
        for system in set(order) - set(frame["system"]):
            ax.text(sum(ax.get_xlim()) / 2, position[system], "none in this cell", ha="center", va="center",
                    color="#666666", fontsize="small", fontstyle="italic",
                    bbox={"facecolor": "white", "edgecolor": "none", "pad": 1})
    fig.supxlabel(xlabel, fontsize="medium", y=0.005, va="bottom")
    axes[0].set_yticks(list(position.values()), [plain_text(label) for label in position])
    axes[0].set_ylim(-0.5, len(order) - 0.5)
    if len(estimates) > 1:
        axes[-1].legend(bbox_to_anchor=(1.02, 1), loc="upper left", fontsize="small")
    return fig


def preference_plot(pairs: pd.DataFrame) -> Figure:
    """Stacked bars per pair: share preferring system_a, no preference, preferring system_b."""
    cells = _cells(pairs)
    labels = sorted({f"{r.system_a} vs {r.system_b}" for r in pairs.itertuples()}, reverse=True)
    position = {label: i for i, label in enumerate(labels)}
    fig, axes = _cell_axes(cells, labels, legend_in=1.3)
    for ax, cell in zip(axes, cells):
        frame = _in_cell(pairs, cell)
        y = np.array([position[f"{r.system_a} vs {r.system_b}"] for r in frame.itertuples()])
        n = frame["n_pages"].to_numpy(dtype=float)
        a, tie, b = (frame[c].to_numpy(dtype=float) / n for c in ("wins_a", "no_preference", "wins_b"))
        ax.barh(y, a, color="#2c7fb8", label="prefer first")
        ax.barh(y, tie, left=a, color="#d9d9d9", label="no preference")
        ax.barh(y, b, left=a + tie, color="#fdae61", label="prefer second")
        decided = 1 - tie
        # the Wilson interval of the share among decided pages, drawn on the page scale
        low = frame["share_ci_low"].to_numpy(dtype=float) * decided
        high = frame["share_ci_high"].to_numpy(dtype=float) * decided
        # a and the interval's end are one number computed two ways where every decided page
        # went one way: a rounding difference must not make an error bar negative.
        error = np.clip(np.nan_to_num(np.vstack([a - low, high - a])), 0.0, None)
        ax.errorbar(a, y, xerr=error, fmt="none", ecolor="black", capsize=3)
        ax.axvline(0.5, color="black", linewidth=0.6, linestyle=":")
        ax.set_xlim(0, 1)
        ax.set_title(plain_text(f"{cell[0]} · {cell[1]}"), fontsize="medium")
        ax.set_xlabel("share of pages")
    axes[0].set_yticks(list(position.values()), [plain_text(label) for label in position])
    axes[0].set_ylim(-0.5, len(labels) - 0.5)
    axes[-1].legend(bbox_to_anchor=(1.02, 1), loc="upper left", fontsize="small")
    return fig


def appropriateness_plots(shares: pd.DataFrame, scores: pd.DataFrame, order: Sequence[str]) -> dict[str, Figure]:
    """`matched_preference` and `appropriateness_scores` as two figures, with a dotted line
    where motion shows no sign of the control it was made for (50 %, a score of 0)."""
    figures = {
        "matched_preference": (scale_plot(shares, [("matched", "share_matched", "ci_low", "ci_high")],
                                          "share preferring the matched clip (Wilson 95 % CI)", order, (0, 1)), 0.5),
        "appropriateness_scores": (scale_plot(scores, [("score", "mean_score", "ci_low", "ci_high")],
                                              "mean appropriateness score, -2..+2 (bootstrap 95 % CI)", order,
                                              (-2, 2)), 0.0),
    }
    for fig, chance in figures.values():
        for ax in fig.axes:
            ax.axvline(chance, color="black", linewidth=0.6, linestyle=":")
    return {name: fig for name, (fig, _) in figures.items()}
