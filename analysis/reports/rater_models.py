"""Rater- and clip-aware models of single-clip and side-by-side ratings, as a report:
the crossed linear mixed model (`analysis.raters.crossed_mixed`), the cumulative link mixed
model for Likert scales (`analysis.raters.ordinal_mixed`) and rater agreement
(`analysis.raters.agreement`), with a paragraph per cell.

The cumulative link model needs a Likert scale: at most ``ORDINAL_MAX_POINTS`` points
(a 0-100 slider has 101 possible values, each a threshold to estimate), so cells of
wider scales get the linear model and agreement only, and a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from analysis.raters.agreement import rater_agreement
from analysis.raters.crossed_mixed import CrossedModelTables, crossed_mixed_model
from analysis.stats.minimums import cells_for_models
from analysis.raters.ordinal_mixed import OrdinalModelTables, ordinal_mixed_model
from analysis.stats.anova import CELL
from analysis.reports.tables import write_table

ORDINAL_MAX_POINTS = 11


@dataclass
class RaterModels:
    crossed: CrossedModelTables
    ordinal: OrdinalModelTables
    agreement: pd.DataFrame
    notes: list[str] = field(default_factory=list)

    def tables(self) -> dict[str, tuple[str, pd.DataFrame]]:
        """File name -> (title, table), in the order a report shows them."""
        return {
            "crossed_mixed_estimates": ("Crossed linear mixed model (REML, random intercepts for "
                                        "participants and clips): system means", self.crossed.estimates),
            "crossed_mixed_contrasts": ("Crossed linear mixed model: contrasts against the reference, "
                                        "Wald z, Holm corrected", self.crossed.contrasts),
            "crossed_mixed_variance": ("Crossed linear mixed model: variance components",
                                       self.crossed.variance_components),
            "ordinal_mixed_thresholds": ("Cumulative link mixed model (logit, Laplace): thresholds",
                                         self.ordinal.thresholds),
            "ordinal_mixed_effects": ("Cumulative link mixed model: log-odds of a higher rating than the "
                                      "reference, Wald z, Holm corrected", self.ordinal.effects),
            "ordinal_mixed_random": ("Cumulative link mixed model: random-effect standard deviations",
                                     self.ordinal.random_effects),
            "rater_agreement": ("Krippendorff's alpha over the clips rated twice or more", self.agreement),
        }


def build_rater_models(kept: pd.DataFrame, reference: str | None = None,
                       alpha: float = 0.05) -> RaterModels:
    """The three analyses of a single or side-by-side table's compared ratings; the two
    models only in the cells with enough ratings for them (`analysis.stats.minimums`)."""
    modelled, too_few = cells_for_models(kept, "rater- and clip-aware models")
    agreement, agreement_notes = rater_agreement(kept)
    points = modelled["scale_max"] - modelled["scale_min"] + 1
    likert = modelled[points <= ORDINAL_MAX_POINTS]
    notes = [f"No cumulative link mixed model for {task}: its {lo}-{hi} scale has more than "
             f"{ORDINAL_MAX_POINTS} points (the linear model reads it as numbers)."
             for task, lo, hi in modelled.loc[points > ORDINAL_MAX_POINTS, ["task", "scale_min", "scale_max"]]
             .drop_duplicates().itertuples(index=False)]
    crossed = crossed_mixed_model(modelled, reference, alpha=alpha)
    ordinal = (ordinal_mixed_model(likert, reference, alpha=alpha) if len(likert)
               else OrdinalModelTables(pd.DataFrame(), pd.DataFrame(), pd.DataFrame()))
    return RaterModels(crossed, ordinal, agreement,
                       too_few + crossed.notes + notes + ordinal.notes + agreement_notes)


def _in_cell(table: pd.DataFrame, task: str, cc: str) -> pd.DataFrame:
    return table[(table["task"] == task) & (table["control_class"] == cc)] if len(table) else table


def _p_text(p: float) -> str:
    return "p < .001" if p < 0.001 else f"p = {p:.3f}".replace("0.", ".", 1)


def rater_models_text(models: RaterModels) -> str:
    """A paragraph per cell: the variance components, the contrasts, the ordinal model's
    odds ratios and the agreement."""
    out = []
    cells = models.crossed.variance_components[list(CELL)].drop_duplicates() if len(
        models.crossed.variance_components) else pd.DataFrame(columns=list(CELL))
    for task, cc in cells.itertuples(index=False):
        parts = _in_cell(models.crossed.variance_components, task, cc).set_index("component")["sd"]
        contrasts = _in_cell(models.crossed.contrasts, task, cc)
        text = (f"**{task} · {cc}.** A linear mixed model with crossed random intercepts for "
                f"participants and clips (REML) puts the standard deviation between participants "
                f"at {parts.iloc[0]:.2f}, between clips at {parts.iloc[1]:.2f} and of the residual at "
                f"{parts.iloc[2]:.2f}.")
        if len(contrasts):
            text += (f" Against {contrasts['reference'].iloc[0]} (Wald z, Holm-corrected): "
                     + "; ".join(f"{r.system} {r.difference:+.2f} [{r.ci_low:.2f}, {r.ci_high:.2f}], "
                                 f"{_p_text(r.p_holm)}" for r in contrasts.itertuples(index=False)) + ".")
        effects = _in_cell(models.ordinal.effects, task, cc)
        if len(effects):
            sds = _in_cell(models.ordinal.random_effects, task, cc).set_index("component")["sd"]
            text += (" A cumulative link (logit) mixed model, by the Laplace approximation, gives the "
                     f"odds of a higher rating than {effects['reference'].iloc[0]} as "
                     + "; ".join(f"{r.system} {r.odds_ratio:.2f}, {_p_text(r.p_holm)}"
                                 for r in effects.itertuples(index=False))
                     + f", with random-effect standard deviations {sds.iloc[0]:.2f} (participants) "
                       f"and {sds.iloc[1]:.2f} (clips) on the logit scale.")
        agree = _in_cell(models.agreement, task, cc)
        if len(agree):
            a = agree.iloc[0]
            text += (f" Krippendorff's alpha over the {int(a['stimuli'])} clips rated twice or more is "
                     f"{a['alpha_interval']:.2f} (interval; ordinal {a['alpha_ordinal']:.2f}).")
        out.append(text)
    return "\n\n".join(out)


def write_rater_models(models: RaterModels, folder: str | Path) -> list[Path]:
    """Write the non-empty tables under folder/tables."""
    written = []
    for name, (title, table) in models.tables().items():
        if len(table):
            written += write_table(table, Path(folder) / "tables", name, caption=f"{title}.")
    return written
