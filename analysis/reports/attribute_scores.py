"""HVRNN's Table 2 and Fig. 4 from attribute-classifier outputs: IS and FID per set of
sequences, and a t-SNE map of the classifiers' activations.

The classifiers live in ``generation`` (``python -m generation hvrnn-eval`` runs them on
real and generated sequences); this module reads what they produced, an ``.npz``
without pickles holding:

    sets (string array)        the set names in table order, the reference among them
    reference (string)         the set FID compares every other set with
    actions, styles (strings)  the label vocabularies
    SET/action_probabilities, SET/style_probabilities    (n, classes)
    SET/action_activations, SET/style_activations        (n, features), penultimate layer
    SET/action, SET/style      (n,) label indices each sequence was asked for (or has)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (the backend must be chosen first)
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from analysis.reports import plots  # noqa: E402
from analysis.errors import AnalysisInputError  # noqa: E402
from analysis.motion.scores import frechet_distance, inception_score  # noqa: E402
from analysis.reports.tables import write_table  # noqa: E402
from analysis.motion.tsne import tsne  # noqa: E402

KINDS = ("action", "style")
QUANTITIES = ("probabilities", "activations")


@dataclass(frozen=True)
class ClassifierOutputs:
    sets: dict[str, dict[str, np.ndarray]]  # set name -> {"action_probabilities": ..., ...}
    reference: str
    actions: tuple[str, ...]
    styles: tuple[str, ...]


def read_classifier_outputs(path: str | Path) -> ClassifierOutputs:
    """The classifier outputs file, checked for every array the table needs."""
    path = Path(path)
    if not path.is_file():
        raise AnalysisInputError(f"{path}: no such classifier outputs file")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except (OSError, ValueError) as error:
        raise AnalysisInputError(f"{path}: not a readable .npz file ({error})") from None
    for key in ("sets", "reference", "actions", "styles"):
        if key not in arrays:
            raise AnalysisInputError(f"{path}: no '{key}' array; write the file with 'python -m generation hvrnn-eval'")
    names = [str(s) for s in arrays["sets"]]
    reference = str(arrays["reference"])
    if reference not in names:
        raise AnalysisInputError(f"{path}: the reference set {reference!r} is not among the sets {names}")
    sets = {}
    for name in names:
        wanted = [f"{kind}_{q}" for kind in KINDS for q in QUANTITIES] + list(KINDS)
        missing = [w for w in wanted if f"{name}/{w}" not in arrays]
        if missing:
            raise AnalysisInputError(f"{path}: set {name!r} lacks {', '.join(missing)}")
        sets[name] = {w: arrays[f"{name}/{w}"] for w in wanted}
        if len({len(a) for a in sets[name].values()}) != 1:
            raise AnalysisInputError(f"{path}: the arrays of set {name!r} disagree on the number of sequences")
    return ClassifierOutputs(sets, reference, tuple(str(a) for a in arrays["actions"]), tuple(str(s) for s in arrays["styles"]))


def score_table(outputs: ClassifierOutputs) -> pd.DataFrame:
    """One row per set: sequences, IS and FID (against the reference set) of each classifier.

    IS lies between 1 and the number of classes; the reference set's FID (0 by
    definition) is left empty.
    """
    reference = outputs.sets[outputs.reference]
    rows = []
    for name, arrays in outputs.sets.items():
        row = {"set": name, "sequences": len(arrays["action"])}
        for kind in KINDS:
            row[f"IS {kind}"] = inception_score(arrays[f"{kind}_probabilities"])
        for kind in KINDS:
            row[f"FID {kind}"] = (np.nan if name == outputs.reference else
                                  frechet_distance(reference[f"{kind}_activations"], arrays[f"{kind}_activations"]))
        rows.append(row)
    return pd.DataFrame(rows)


def tsne_figure(outputs: ClassifierOutputs, kind: str = "action", perplexity: float = 30.0) -> Figure:
    """Fig. 4: one t-SNE map of every set's ``kind``-classifier activations, one panel per
    set; a panel shows its set coloured by the label it was asked for over all points in grey."""
    if kind not in KINDS:
        raise AnalysisInputError(f"unknown classifier {kind!r}; use one of {KINDS}")
    names = list(outputs.sets)
    activations = [outputs.sets[n][f"{kind}_activations"] for n in names]
    points = tsne(np.concatenate(activations), perplexity=min(perplexity, (sum(map(len, activations)) - 1) / 3))
    bounds = np.cumsum([0] + [len(a) for a in activations])
    labels = outputs.actions if kind == "action" else outputs.styles
    # tab20 without its two greys (the background is grey), then tab20b for more labels.
    palette = np.concatenate([np.delete(plt.get_cmap("tab20")(np.arange(20)), [14, 15], axis=0),
                              plt.get_cmap("tab20b")(np.arange(20))])
    colours = palette[np.arange(len(labels)) % len(palette)]
    columns = min(4, len(names))
    rows = -(-len(names) // columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.2 * columns + 1.8, 3.2 * rows), squeeze=False)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    for i, (name, ax) in enumerate(zip(names, axes.flat)):
        ax.scatter(points[:, 0], points[:, 1], s=6, c="0.85", linewidths=0)
        own = points[bounds[i] : bounds[i + 1]]
        ax.scatter(own[:, 0], own[:, 1], s=12, c=colours[outputs.sets[name][kind]], linewidths=0)
        ax.set_title(plots.plain_text(name) + (" (reference)" if name == outputs.reference else ""), fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    handles = [plt.Line2D([], [], marker="o", linestyle="", color=colours[j], label=plots.plain_text(label))
               for j, label in enumerate(labels)]
    fig.legend(handles=handles, loc="center right", fontsize=7, frameon=False, title=kind)
    fig.subplots_adjust(left=0.02, right=1 - 1.7 / (3.2 * columns + 1.8), bottom=0.03, top=0.92, wspace=0.05, hspace=0.15)
    return fig


def write_scores(path: str | Path, out: str | Path) -> pd.DataFrame:
    """Read a classifier outputs file; write Table 2 (tables/) and Fig. 4 for both classifiers (figures/)."""
    outputs = read_classifier_outputs(path)
    table = score_table(outputs)
    out = Path(out)
    write_table(table.round(3), out / "tables", "table2_is_fid",
                caption=f"IS and FID of the attribute classifiers; FID against {outputs.reference!r}.")
    for kind in KINDS:
        plots.save_figure(tsne_figure(outputs, kind), out / "figures", f"tsne_{kind}")
    return table
