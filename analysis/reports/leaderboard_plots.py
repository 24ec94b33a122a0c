"""The leaderboard's figures, as Chatbot Arena draws them: per task x control class, a
heat map of the share of decided pages the row system won against the column system,
and one of how many pages showed each pair (battles), rows and columns in leaderboard
order (best first)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from analysis.reports.plots import plain_text, plt

HEAT_MAPS = {
    "win_fraction": ("share of decided pages the row system won", "RdBu", (0.0, 1.0), "{:.2f}"),
    "battles": ("pages showing both systems", "Blues", None, "{:.0f}"),
}


def _order(board: pd.DataFrame, pairs: pd.DataFrame, task: str, control_class: str) -> list[str]:
    ranked = board[(board["task"] == task) & (board["control_class"] == control_class)]
    if len(ranked):
        return list(ranked.sort_values("rank", kind="stable")["system"])
    return sorted(set(pairs["system"]) | set(pairs["opponent"]))


def heat_map_plot(pairs: pd.DataFrame, board: pd.DataFrame, value: str) -> Figure:
    """``value`` (a key of `HEAT_MAPS`) of `analysis.rankings.leaderboard.battles` per ordered pair,
    one panel per cell, systems ordered by ``board`` (`analysis.rankings.leaderboard.leaderboard`)."""
    title, colours, limits, label = HEAT_MAPS[value]
    cells = sorted(pairs.groupby(["task", "control_class"]).groups)
    size = max(len(_order(board, pairs[(pairs["task"] == t) & (pairs["control_class"] == c)], t, c))
               for t, c in cells)
    side = 1.2 + 0.55 * size
    fig, axes = plt.subplots(1, len(cells), figsize=(side * len(cells) + 1.2, side + 0.5), squeeze=False)
    for ax, (task, cc) in zip(axes[0], cells):
        frame = pairs[(pairs["task"] == task) & (pairs["control_class"] == cc)]
        order = _order(board, frame, task, cc)
        matrix = (frame.pivot(index="system", columns="opponent", values=value)
                  .reindex(index=order, columns=order).to_numpy(dtype=np.float64))
        vmin, vmax = limits if limits else (0.0, np.nanmax(matrix) if np.isfinite(matrix).any() else 1.0)
        image = ax.imshow(np.ma.masked_invalid(matrix), cmap=colours, vmin=vmin, vmax=vmax)
        for (i, j), number in np.ndenumerate(matrix):
            if np.isfinite(number):
                dark = (number - vmin) / ((vmax - vmin) or 1.0)
                ax.text(j, i, label.format(number), ha="center", va="center", fontsize="x-small",
                        color="white" if (dark > 0.75 or (limits and dark < 0.25)) else "black")
        ax.set_xticks(range(len(order)), [plain_text(s) for s in order], rotation=90)
        ax.set_yticks(range(len(order)), [plain_text(s) for s in order])
        ax.set_title(plain_text(f"{task} · {cc}"), fontsize="medium")
        ax.set_xlabel("opponent")
        fig.colorbar(image, ax=ax, shrink=0.8, label=title)
    axes[0][0].set_ylabel("system")
    fig.tight_layout()
    return fig


def pairing_plot(summary: pd.DataFrame) -> Figure:
    """`analysis.reports.pairing_simulation.pairing_summary`: Kendall's tau and the mean interval
    width against the votes, one line per pairing, error bars of one standard error."""
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.4))
    for pairing, frame in summary.groupby("pairing", sort=True):
        for ax, (value, error) in zip(axes, (("kendall_tau", "tau_se"), ("mean_width", "width_se"))):
            ax.errorbar(frame["votes"], frame[value], yerr=frame[error], marker="o", capsize=3,
                        label=plain_text(pairing))
    axes[0].set_ylabel("Kendall's tau with the true order")
    axes[1].set_ylabel("mean 95 % interval width (Elo)")
    for ax in axes:
        ax.set_xlabel("votes (pages)")
    axes[0].legend(fontsize="small")
    fig.tight_layout()
    return fig
