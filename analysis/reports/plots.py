"""The report's figures: mean ratings with CIs, rating distributions, footstep curves.

Each function returns a matplotlib Figure (so the study app can embed it); `save_figure`
writes PNG and SVG. The Agg backend is used: no display is needed anywhere.

Drawing text dominates matplotlib's time, and a report must take seconds, so panels
share their system axis (labels drawn once), margins are set from the label length
instead of by tight_layout (which draws the figure an extra time), and SVG keeps text
as text rather than converting every glyph to a path.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from analysis.reports.tables import system_order  # noqa: E402


_CHAR_WIDTH_IN = 0.075  # tick label character width at the default 10 pt font


def plain_text(label) -> str:
    """A label from the data drawn as written: matplotlib reads text between two "$" as
    TeX math, and a system named "$\\undefined{$" would stop the figure."""
    return str(label).replace("$", r"\$")


def _cell_axes(cells: list[tuple], labels, width: float = 3.6, height: float = 3.2,
               legend_in: float = 0.0):
    """One panel per cell in a row, sharing the system axis, margins fixed up front."""
    left_in = 0.3 + _CHAR_WIDTH_IN * max(len(str(label)) for label in labels)
    fig_width = left_in + width * len(cells) + legend_in + 0.2
    fig, axes = plt.subplots(1, len(cells), figsize=(fig_width, height), squeeze=False, sharey=True)
    fig.subplots_adjust(left=left_in / fig_width, right=1 - (legend_in + 0.2) / fig_width,
                        bottom=0.16, top=0.9, wspace=0.08)
    return fig, axes[0]


def rating_scale(ratings: pd.DataFrame) -> tuple[int, int] | None:
    """The one scale (lowest, highest) all ``ratings`` are on; None where they have no
    scale columns or mix scales."""
    if not {"scale_min", "scale_max"} <= set(ratings.columns) or not len(ratings):
        return None
    scales = ratings[["scale_min", "scale_max"]].drop_duplicates()
    return (int(scales.iloc[0, 0]), int(scales.iloc[0, 1])) if len(scales) == 1 else None


def interval_errors(centre, low, high, limits: tuple[float, float] | None = None) -> np.ndarray:
    """``errorbar``'s (2, n) xerr of intervals [low, high] about ``centre``, cut at the ends
    of ``limits`` (a rating scale: no mean lies outside it); 0 where an end is missing."""
    centre, low, high = (np.asarray(x, dtype=float) for x in (centre, low, high))
    if limits is not None:
        low, high = np.maximum(low, limits[0]), np.minimum(high, limits[1])
    return np.nan_to_num(np.vstack([centre - low, high - centre]))


def fit_scale(ax, limits: tuple[float, float] | None) -> None:
    """The value axis spans the rating scale (a little beyond its ends), integer points
    marked on a short scale, quarters on a share's 0..1."""
    if limits is None:
        return
    low, high = limits
    pad = 0.04 * (high - low)
    ax.set_xlim(low - pad, high + pad)
    if high - low <= 1:  # a share: quarters
        ax.set_xticks(np.linspace(low, high, 5), [f"{tick:g}" for tick in np.linspace(low, high, 5)])
    elif high - low <= 10:
        ax.set_xticks(np.arange(low, high + 1))


def means_plot(means: pd.DataFrame, reference: str | None = None,
               scale: tuple[int, int] | None = None, singles: pd.DataFrame | None = None) -> Figure:
    """Mean rating and 95 % CI per system, one panel per task x control class; with the
    ``scale``, the axis spans it and the intervals are cut at its ends. ``singles``: the
    ratings (task, control_class, system, value) of a system rated only once in a cell,
    which has a mean but no interval: drawn hollow, without one, and said in its panel's legend."""
    singles = singles if singles is not None else pd.DataFrame(columns=["task", "control_class", "system", "value"])
    cells = sorted(set(means.groupby(["task", "control_class"]).groups)
                   | set(singles.groupby(["task", "control_class"]).groups))
    order = system_order(pd.concat([means["system"], singles["system"]]).unique(), reference)
    position = {system: len(order) - 1 - i for i, system in enumerate(order)}
    fig, axes = _cell_axes(cells, order)
    for ax, cell in zip(axes, cells):
        frame = means[(means["task"] == cell[0]) & (means["control_class"] == cell[1])]
        ax.errorbar(frame["mean"], frame["system"].map(position),
                    xerr=interval_errors(frame["mean"], frame["ci_low"], frame["ci_high"], scale), fmt="o", capsize=3)
        single = singles[(singles["task"] == cell[0]) & (singles["control_class"] == cell[1])]
        if len(single):
            ax.plot(single["value"].astype(float), single["system"].map(position), "o", color="C0", mfc="none",
                    label="one rating: no interval")
            ax.legend(loc="best", fontsize="small")
        ax.set_title(plain_text(f"{cell[0]} · {cell[1]}"), fontsize="medium")
        ax.set_xlabel("mean rating (95 % CI)")
        fit_scale(ax, scale)
    axes[0].set_yticks(list(position.values()), [plain_text(s) for s in position])
    axes[0].set_ylim(-0.5, len(order) - 0.5)
    return fig


def distribution_plot(ratings: pd.DataFrame, reference: str | None = None) -> Figure:
    """Share of each rating value per system (stacked bars), one panel per cell."""
    cells = sorted(ratings.groupby(["task", "control_class"]).groups)
    order = system_order(ratings["system"].unique(), reference)[::-1]
    counts = ratings.groupby(["task", "control_class", "system", "value"]).size()
    fig, axes = _cell_axes(cells, order, legend_in=0.7)
    for ax, cell in zip(axes, cells):
        frame = ratings[(ratings["task"] == cell[0]) & (ratings["control_class"] == cell[1])]
        lo, hi = int(frame["scale_min"].iloc[0]), int(frame["scale_max"].iloc[0])
        shares = counts.loc[cell].unstack("value", fill_value=0)
        shares = shares.reindex(index=order, columns=range(lo, hi + 1), fill_value=0)
        shares = shares.div(shares.sum(axis=1).replace(0, 1), axis=0)
        left = np.zeros(len(shares))
        colours = plt.cm.RdYlGn(np.linspace(0.05, 0.95, hi - lo + 1))
        for value, colour in zip(shares.columns, colours):
            ax.barh(np.arange(len(order)), shares[value], left=left, color=colour, label=str(value))
            left += shares[value].to_numpy()
        ax.set_xlim(0, 1)
        ax.set_title(plain_text(f"{cell[0]} · {cell[1]}"), fontsize="medium")
        ax.set_xlabel("share of ratings")
    axes[0].set_yticks(np.arange(len(order)), [plain_text(s) for s in order])
    axes[-1].legend(title="rating", bbox_to_anchor=(1.02, 1), loc="upper left", fontsize="small")
    return fig


def footstep_plot(curves: pd.DataFrame, natural: str = "NAT") -> Figure:
    """f_est against v_tol per system (MoGlow Fig. 5)."""
    fig, ax = plt.subplots(figsize=(5.5, 3.5))
    for system in system_order(curves["system"], natural):
        frame = curves[curves["system"] == system]
        ax.plot(frame["v_tol"], frame["f_est"], label=plain_text(system),
                linewidth=2.0 if system == natural else 1.2)
    ax.set_xlabel("speed tolerance $v_{tol}$ (cm/s)")
    ax.set_ylabel("$f_{est}$ (footsteps/s)")
    ax.legend(fontsize="small")
    fig.tight_layout()
    return fig


def adherence_plot(curves: pd.DataFrame, natural: str = "NAT") -> Figure:
    """Position and heading error over the clips' time per system (`analysis.reports.adherence`)."""
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.4))
    for system, curve in curves.groupby("system", sort=True):
        width = 2.0 if system == natural else 1.2
        for ax, column in zip(axes, ("position_error", "heading_error")):
            ax.plot(curve["time_s"], curve[column], label=plain_text(system), linewidth=width)
    axes[0].set_ylabel("distance from the control's path (cm)")
    axes[1].set_ylabel("heading error (degrees)")
    for ax in axes:
        ax.set_xlabel("time in the clip (s)")
    axes[1].legend(fontsize="small")
    fig.tight_layout()
    return fig


def metric_agreement_plot(agreement: pd.DataFrame, per_system: pd.DataFrame, natural: str = "NAT") -> Figure:
    """Per metric, each system's mean metric against its mean rating, Kendall's tau (and its
    bootstrap interval) in the title (`analysis.reports.metric_agreement`)."""
    metrics = list(agreement["metric"])
    columns = min(3, len(metrics))
    rows = -(-len(metrics) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.4 * columns, 3.0 * rows), squeeze=False)
    for ax, row in zip(axes.ravel(), agreement.itertuples(index=False)):
        points = per_system[per_system["metric"] == row.metric]
        ax.scatter(points["metric_mean"], points["rating_mean"], s=18)
        for point in points.itertuples(index=False):
            ax.annotate(plain_text(point.system), (point.metric_mean, point.rating_mean), fontsize="x-small",
                        fontweight="bold" if point.system == natural else "normal",
                        xytext=(3, 3), textcoords="offset points")
        ax.set_title(f"{plain_text(row.metric)}\nτ = {row.tau:.2f} [{row.ci_low:.2f}, {row.ci_high:.2f}]",
                     fontsize="small")
        ax.set_xlabel("mean over the system's clips", fontsize="small")
        ax.set_ylabel("mean rating", fontsize="small")
    for ax in axes.ravel()[len(metrics):]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, folder: str | Path, name: str) -> list[Path]:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / f"{name}.png", folder / f"{name}.svg"]
    # Text stays text in the SVG. Matplotlib dates an SVG and names its clip paths by a
    # random salt: without the date and with a fixed salt, the same figure is the same
    # file, so a report computed again (an imported study's) is byte for byte the original.
    with plt.rc_context({"svg.fonttype": "none", "svg.hashsalt": "motion-study"}):
        for path in paths:
            fig.savefig(path, dpi=110, metadata={"Date": None} if path.suffix == ".svg" else None)
    plt.close(fig)
    return paths
